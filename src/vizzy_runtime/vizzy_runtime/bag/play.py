"""Player: publish a bag's messages on DDS with their recorded timing, like `ros2 bag play`."""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from collections.abc import Iterable
from dataclasses import replace
from types import FrameType
from typing import Any

from .. import msgs
from .chunks import CorruptChunk
from .common import BagError, QosProfile, StopRequest, TopicInfo, one_line
from .reader import BagReader

log = logging.getLogger('vizzy_runtime.bag')


def offer_qos(profiles: Iterable[QosProfile], topic: str = '') -> QosProfile:
    """The QoS to publish a recorded topic with (rosbag2's adapt_offer_to_recorded_offers): the
    recorded publishers' profile if they agree on everything that affects matching, with a
    keep_last history of at least 10; ROS defaults when nothing or a mix was recorded."""
    profiles = list(profiles)
    if not profiles:
        return QosProfile()
    first = profiles[0]

    def key(p: QosProfile) -> tuple[Any, ...]:
        return (p.reliability, p.durability, p.deadline_ns, p.liveliness,
                p.liveliness_lease_duration_ns)

    if any(key(p) != key(first) for p in profiles[1:]):
        log.warning('%s: recorded publishers offered different QoS; playing with the defaults',
                    topic or 'topic')
        return QosProfile()
    depth = first.depth if first.history == 'keep_last' else 0
    return replace(first, history='keep_last', depth=max(10, depth))


def ensure_type(typename: str, definitions: dict[str, tuple[str, str]]) -> None:
    """Make `typename` known to the bundled typestore, from the bag's stored definition if
    needed (BagError when neither knows it)."""
    store = msgs.registry().store
    if typename in store.fielddefs:
        return
    encoding, text = definitions.get(typename, ('', ''))
    if encoding != 'ros2msg' or not text:
        raise BagError(f'unknown message type {typename!r}: not in the bundled typestore and '
                       f'the bag stores no .msg definition for it')
    from rosbags.typesys import get_types_from_msg
    try:
        types = get_types_from_msg(text, typename)
        store.register({k: v for k, v in types.items() if k not in store.fielddefs})
    except Exception as exc:  # noqa: BLE001 - rosbags' parser errors have several types
        raise BagError(f'message type {typename!r}: bad definition in the bag: '
                       f'{one_line(exc)}') from None


class Player:
    """Publish a bag's messages with their recorded timing.

    Args:
        bag_dir: the bag directory.
        rate: playback speed factor (2.0 = twice as fast); the gaps between log times are
            divided by it, each message waits for its own wall-clock deadline (no drift).
        topics: topics to play (default: all); BagError names any not in the bag.
        loop: start over at the end until stopped.
        wait_for_subscribers: wait up to this many seconds, before the first message, until
            every topic's writer has a matched subscriber.

    Each topic gets one DDS writer with the recorded offered QoS; CDR bytes are written as
    stored. run() blocks until done, stop() or SIGINT/SIGTERM; it returns counts per topic.
    A corrupt chunk (does not decompress, fails its CRC) is skipped with a one-line warning and
    the rest is played; corrupt_chunks lists those skipped.
    """

    def __init__(self, bag_dir: str | os.PathLike[str], *, rate: float = 1.0,
                 topics: Iterable[str] | None = None, loop: bool = False,
                 wait_for_subscribers: float = 0.0) -> None:
        if not rate > 0:
            raise ValueError(f'rate must be > 0, got {rate}')
        self.rate = rate
        self.loop = loop
        self.wait_for_subscribers = wait_for_subscribers
        self.reader = BagReader(bag_dir)
        available = self.reader.topics
        names = list(available) if topics is None else list(topics)
        missing = sorted(set(names) - set(available))
        if missing:
            raise BagError(f'{self.reader.path}: no topic(s) {", ".join(missing)} in the bag '
                           f'(it has {", ".join(sorted(available)) or "none"})')
        self.topics: list[TopicInfo] = [available[n] for n in names]
        self._stop = StopRequest()  # set from signal handlers: threading.Event is not safe there

    def stop(self) -> None:
        """Ask run() to finish (thread- and signal-safe)."""
        self._stop.set()

    @property
    def corrupt_chunks(self) -> list[CorruptChunk]:
        """Chunks skipped so far because they did not decode (their messages were not played)."""
        return self.reader.corrupt_chunks

    def run(self, *, handle_signals: bool = True) -> dict[str, int]:
        """Play (once, or looping) and return the messages published per topic.

        Args:
            handle_signals: in the main thread, turn SIGINT/SIGTERM into stop().
        """
        from .. import dds
        definitions = self.reader.definitions()
        for topic in self.topics:
            ensure_type(topic.type, definitions)
        writers: dict[str, Any] = {}
        counts = {t.name: 0 for t in self.topics}
        old = self._install_signals() if handle_signals else {}
        try:
            for t in self.topics:
                qos = offer_qos(t.offered_qos_profiles, t.name).to_dds()
                writers[t.name] = dds.RawWriter(t.name, t.type, qos)
            if self.wait_for_subscribers > 0:
                self._wait_for_subscribers(writers)
            while not self._stop.is_set():
                self._play_once(writers, counts)
                if not self.loop:
                    break
        finally:
            # Deleting a reliable writer lingers until readers acknowledged what it sent.
            for w in writers.values():
                dds.delete(w)
            for sig, handler in old.items():
                signal.signal(sig, handler)
        return counts

    def _wait_for_subscribers(self, writers: dict[str, Any]) -> None:
        deadline = time.monotonic() + self.wait_for_subscribers
        while not self._stop.is_set():
            lonely = [name for name, w in writers.items() if w.matched_count() == 0]
            if not lonely:
                return
            if time.monotonic() >= deadline:
                log.warning('no subscriber after %.1f s on %s; playing anyway',
                            self.wait_for_subscribers, ', '.join(lonely))
                return
            self._stop.wait(0.01)

    def _play_once(self, writers: dict[str, Any], counts: dict[str, int]) -> None:
        wall0 = bag0 = None
        for msg in self.reader.messages(topics=list(writers)):
            if wall0 is None or bag0 is None:
                wall0, bag0 = time.monotonic(), msg.log_time_ns
            # Deadlines from the start, not from the previous message: sleep error never adds up.
            delay = wall0 + (msg.log_time_ns - bag0) / 1e9 / self.rate - time.monotonic()
            if self._stop.wait(delay) if delay > 0 else self._stop.is_set():
                return
            writers[msg.topic].write(msg.data)
            counts[msg.topic] += 1

    def _install_signals(self) -> dict[int, Any]:
        if threading.current_thread() is not threading.main_thread():
            return {}

        def handler(signum: int, _frame: FrameType | None) -> None:
            self.stop()

        return {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
