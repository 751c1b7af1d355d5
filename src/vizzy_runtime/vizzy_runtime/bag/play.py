"""Player: publish a bag's messages on DDS with their recorded timing, like `ros2 bag play`:
rate, topic selection, loop, remapping, a start offset, /clock from the bag's time (--clock) and
rosbag2's progress line."""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Iterable, Mapping
from dataclasses import replace
from types import FrameType
from typing import IO, Any

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


CLOCK_TOPIC = '/clock'
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
DEFAULT_CLOCK_HZ = 40.0        # `ros2 bag play --clock` without a frequency


def parse_remaps(rules: Iterable[str]) -> dict[str, str]:
    """`--remap from:=to ...` (topic names; a relative one is taken from the root namespace,
    as rosbag2's player node sits there): ValueError names a rule it cannot read."""
    out: dict[str, str] = {}
    for rule in rules:
        src, sep, dst = rule.partition(':=')
        if not sep or not src or not dst:
            raise ValueError(f"--remap {rule!r}: expected 'from:=to' (e.g. /old:=/new)")
        if src.startswith('__') or ':' in src:
            raise ValueError(f'--remap {rule!r}: only topic names can be remapped here')
        out['/' + src.lstrip('/')] = '/' + dst.lstrip('/')
    return out


class ProgressLine:
    """rosbag2's playback progress (`[bag time] Duration elapsed/total [S]`, S: R running,
    D delayed: waiting for subscribers), one line rewritten in place with a carriage return,
    at most rate_hz times a second (negative: at every message; 0: off)."""

    def __init__(self, stream: IO[str], start_ns: int, end_ns: int, rate_hz: float) -> None:
        self.stream = stream
        self.start_ns = start_ns
        self.duration_s = max(end_ns - start_ns, 0) / 1e9
        self.period = 0.0 if rate_hz < 0 else (1.0 / rate_hz if rate_hz > 0 else None)
        self._last = -float('inf')
        self.drawn = False

    def update(self, bag_ns: int, status: str = 'R', force: bool = False) -> None:
        if self.period is None:
            return
        now = time.monotonic()
        if not force and now - self._last < self.period:
            return
        self._last = now
        sec, nsec = divmod(bag_ns, 10**9)     # exact, where a float's 9 decimals are not
        self.stream.write(f'\r[{sec}.{nsec:09d}] Duration {(bag_ns - self.start_ns) / 1e9:.2f}'
                          f'/{self.duration_s:.2f} [{status}]   ')
        self.stream.flush()
        self.drawn = True

    def close(self) -> None:
        if self.drawn:    # what follows starts on a line of its own
            self.stream.write('\n')
            self.stream.flush()
            self.drawn = False


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
        remap: topic name in the bag -> name to publish on (BagError if two topics of different
            types would share one).
        start_offset: start this many seconds into the bag (its first message's time + offset).
        clock_hz: publish rosgraph_msgs/Clock on /clock at this rate, from the bag's time as
            played (the bag's own /clock is then not played, as rosbag2 does); 0: off.
        progress_hz: print rosbag2's progress line on progress_stream at this rate (0: off,
            negative: at every message).

    Each topic gets one DDS writer with the recorded offered QoS; CDR bytes are written as
    stored. run() blocks until done, stop() or SIGINT/SIGTERM; it returns counts per topic.
    A corrupt chunk (does not decompress, fails its CRC) is skipped with a one-line warning and
    the rest is played; corrupt_chunks lists those skipped.
    """

    def __init__(self, bag_dir: str | os.PathLike[str], *, rate: float = 1.0,
                 topics: Iterable[str] | None = None, loop: bool = False,
                 wait_for_subscribers: float = 0.0, remap: Mapping[str, str] | None = None,
                 start_offset: float = 0.0, clock_hz: float = 0.0, progress_hz: float = 0.0,
                 progress_stream: IO[str] | None = None) -> None:
        if not rate > 0:
            raise ValueError(f'rate must be > 0, got {rate}')
        if not start_offset >= 0:
            raise ValueError(f'start offset must be >= 0 s, got {start_offset}')
        if not clock_hz >= 0:
            raise ValueError(f'clock rate must be >= 0 Hz, got {clock_hz}')
        self.rate = rate
        self.loop = loop
        self.wait_for_subscribers = wait_for_subscribers
        self.clock_hz = clock_hz
        self.reader = BagReader(bag_dir)
        available = self.reader.topics
        names = list(available) if topics is None else list(topics)
        missing = sorted(set(names) - set(available))
        if missing:
            raise BagError(f'{self.reader.path}: no topic(s) {", ".join(missing)} in the bag '
                           f'(it has {", ".join(sorted(available)) or "none"})')
        if clock_hz and CLOCK_TOPIC in names:
            names.remove(CLOCK_TOPIC)   # rosbag2: --clock publishes /clock instead of the bag's
        self.topics: list[TopicInfo] = [available[n] for n in names]
        self.remap = dict(remap or {})
        for src in sorted(set(self.remap) - set(available)):
            log.warning('--remap %s:=%s: no topic %s in the bag', src, self.remap[src], src)
        published: dict[str, str] = {}
        for t in self.topics:
            name = self.published_name(t.name)
            if published.setdefault(name, t.type) != t.type:
                raise BagError(f'--remap: {name} would carry two types ({published[name]}, '
                               f'{t.type})')
        self.start_ns = self.reader.start_time_ns + round(start_offset * 1e9)
        self.progress = (ProgressLine(progress_stream or sys.stderr, self.start_ns,
                                      self.reader.end_time_ns, progress_hz)
                         if progress_hz else None)
        self._stop = StopRequest()  # set from signal handlers: threading.Event is not safe there

    def published_name(self, topic: str) -> str:
        """The name a bag topic is published on (after --remap)."""
        return self.remap.get(topic, topic)

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
        counts = {self.published_name(t.name): 0 for t in self.topics}
        old = self._install_signals() if handle_signals else {}
        try:
            for t in self.topics:
                qos = offer_qos(t.offered_qos_profiles, t.name).to_dds()
                writers[t.name] = dds.RawWriter(self.published_name(t.name), t.type, qos)
            if self.clock_hz:
                # rclcpp's ClockQoS, which every /clock subscription (TimeSource) matches
                self._clock_writer = dds.RawWriter(CLOCK_TOPIC, CLOCK_TYPE,
                                                   dds.QoS(reliable=False, depth=1))
            if self.wait_for_subscribers > 0:
                self._wait_for_subscribers(writers)
            while not self._stop.is_set():
                self._play_once(writers, counts)
                if not self.loop:
                    break
        finally:
            if self.progress is not None:
                self.progress.close()
            # Deleting a reliable writer lingers until readers acknowledged what it sent.
            for w in [*writers.values(), getattr(self, '_clock_writer', None)]:
                if w is not None:
                    dds.delete(w)
            self._clock_writer = None
            for sig, handler in old.items():
                signal.signal(sig, handler)
        return counts

    _clock_writer: Any = None

    def _publish_clock(self, bag_ns: int) -> None:
        from .. import msgs
        clock = msgs.get_message(CLOCK_TYPE)()
        clock.clock.sec, clock.clock.nanosec = divmod(bag_ns, 10**9)
        self._clock_writer.write(msgs.serialize(clock, CLOCK_TYPE))

    def _wait_for_subscribers(self, writers: dict[str, Any]) -> None:
        deadline = time.monotonic() + self.wait_for_subscribers
        while not self._stop.is_set():
            lonely = [self.published_name(name) for name, w in writers.items()
                      if w.matched_count() == 0]
            if not lonely:
                return
            if time.monotonic() >= deadline:
                if self.progress is not None:
                    self.progress.close()
                log.warning('no subscriber after %.1f s on %s; playing anyway',
                            self.wait_for_subscribers, ', '.join(lonely))
                return
            if self.progress is not None:
                self.progress.update(self.start_ns, 'D')
            self._stop.wait(0.01)

    def _wait(self, until: float, wall0: float, until_ns: int) -> bool:
        """Wait until the monotonic time `until` (the bag time until_ns), publishing /clock ticks
        and the progress line meanwhile; True if stopped."""
        while True:
            now = time.monotonic()
            # the player's clock runs at `rate`, but never past the message still to be sent
            # (a late wake-up must not stamp /clock ahead of data that has not gone out)
            bag_ns = min(self.start_ns + round((now - wall0) * self.rate * 1e9), until_ns)
            wake = until
            if self._clock_writer is not None:
                if now >= self._next_tick:
                    self._publish_clock(bag_ns)
                    # the next tick on the rate's grid; a late one is not made up for
                    self._next_tick = max(self._next_tick + 1.0 / self.clock_hz, now)
                wake = min(wake, self._next_tick)
            if self.progress is not None:
                self.progress.update(bag_ns)
                if self.progress.period:
                    wake = min(wake, now + self.progress.period)
            if now >= until:
                return self._stop.is_set()
            if self._stop.wait(wake - now):
                return True

    def _play_once(self, writers: dict[str, Any], counts: dict[str, int]) -> None:
        # The player's clock starts at the bag's start (+ offset) and runs at `rate`; each message
        # waits for its own deadline from that start: sleep error never adds up.
        wall0 = self._next_tick = time.monotonic()
        for msg in self.reader.messages(topics=list(writers), start_ns=self.start_ns):
            deadline = wall0 + (msg.log_time_ns - self.start_ns) / 1e9 / self.rate
            if self._wait(deadline, wall0, msg.log_time_ns):
                return
            writers[msg.topic].write(msg.data)
            counts[self.published_name(msg.topic)] += 1
            if self.progress is not None and self.progress.period == 0.0:
                self.progress.update(msg.log_time_ns, force=True)
        if self.progress is not None:   # the end, whatever the rate limit let through
            self.progress.update(self.reader.end_time_ns, force=True)

    _next_tick = 0.0

    def _install_signals(self) -> dict[int, Any]:
        if threading.current_thread() is not threading.main_thread():
            return {}

        def handler(signum: int, _frame: FrameType | None) -> None:
            self.stop()

        return {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
