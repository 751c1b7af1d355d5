"""Recorder: ROS 2 topics from DDS into a rosbag2 bag, like `ros2 bag record`."""

from __future__ import annotations

import contextlib
import logging
import os
import queue
import signal
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from types import FrameType
from typing import Any

from .common import BagError, BagMetadata, QosProfile, StopRequest, one_line
from .writer import BagWriter

log = logging.getLogger('vizzy_runtime.bag')

_TAKE = 256


def default_bag_name() -> str:
    """rosbag2's default output name: rosbag2_YYYY_MM_DD-HH_MM_SS."""
    return time.strftime('rosbag2_%Y_%m_%d-%H_%M_%S')


def is_hidden(topic: str) -> bool:
    """Hidden ROS names have a component starting with '_' (skipped unless asked for)."""
    return any(part.startswith('_') for part in topic.split('/'))


def request_qos(offers: list[Any]) -> Any:
    """The reader QoS that matches every publisher (rosbag2's adapt_request_to_offers):
    reliable only if all offer it, transient_local only if all offer it (so /tf_static's
    latched messages are received), and keep_all so a burst is not overwritten before take."""
    from .. import dds
    return dds.QoS(reliable=all(q.reliable for q in offers),
                   transient_local=all(q.transient_local for q in offers), keep_all=True)


class Recorder:
    """Record topics seen on DDS into a new bag directory.

    Args:
        output_dir: bag directory to create (must not exist or be empty).
        topics: topic names to record; None records every topic that has a publisher
            (hidden ones only with include_hidden). Topics are discovered continuously, so
            publishers that appear later are recorded too.
        exclude: topics never to record (like ros2 bag record --exclude-topics).
        include_hidden: also record hidden topics (a name component starting with '_').
        discovery_interval: seconds between looks at the DDS graph.
        chunk_size, flush_interval, compression, custom_data: see BagWriter.

    run() blocks until the duration passes, stop() is called or SIGINT/SIGTERM arrives, then
    finalizes the bag (nothing received is dropped) and returns the per-topic counts. A stop
    that comes before or during start-up (DDS discovery) still ends in a finished, empty bag.
    """

    def __init__(self, output_dir: str | os.PathLike[str], topics: Iterable[str] | None = None,
                 *, exclude: Iterable[str] = (), include_hidden: bool = False,
                 discovery_interval: float = 0.5,
                 chunk_size: int = 1 << 20, flush_interval: float = 1.0,
                 compression: str = 'zstd', custom_data: dict[str, str] | None = None) -> None:
        self.output_dir = Path(output_dir)
        if self.output_dir.exists() and (not self.output_dir.is_dir()
                                         or any(self.output_dir.iterdir())):
            raise BagError(f'{self.output_dir}: already exists, not overwriting')
        self.topics = None if topics is None else {t if t.startswith('/') else '/' + t
                                                   for t in topics}
        self.exclude = {t if t.startswith('/') else '/' + t for t in exclude}
        self.include_hidden = include_hidden
        self.discovery_interval = discovery_interval
        self._writer_args: dict[str, Any] = dict(chunk_size=chunk_size,
                                                 flush_interval=flush_interval,
                                                 compression=compression, custom_data=custom_data)
        self._stop = StopRequest()  # set from signal handlers: threading.Event is not safe there
        self._queue: queue.SimpleQueue[tuple[str, bytes, int, int] | None] = queue.SimpleQueue()
        self._readers: dict[str, Any] = {}
        self._skipped: set[str] = set()
        self._error: BaseException | None = None
        self.writer: BagWriter | None = None
        self.metadata: BagMetadata | None = None

    def stop(self) -> None:
        """Ask run() to finish (thread- and signal-safe; also before run())."""
        self._stop.set()

    def handle_signal(self, signum: int = signal.SIGINT, _frame: FrameType | None = None) -> None:
        """What run() does on SIGINT/SIGTERM (for a caller that keeps its own handler): stop();
        a repeated signal says the bag is being finished. Takes no lock and does not log
        (os.write), so it is safe wherever the main thread was interrupted."""
        if self._stop.is_set():
            with contextlib.suppress(OSError):
                os.write(2, b'[WARNING] finishing the bag, please wait\n')
        self.stop()

    @property
    def counts(self) -> dict[str, int]:
        """Messages written so far, per topic."""
        return self.writer.counts if self.writer else {}

    def run(self, duration: float | None = None, *, handle_signals: bool = True) -> dict[str, int]:
        """Record until `duration` seconds pass (None: forever), stop() or a signal.

        Args:
            duration: seconds to record; None until stopped.
            handle_signals: in the main thread, turn SIGINT/SIGTERM into stop().

        Returns messages recorded per topic. Raises BagError if the bag cannot be written.
        """
        # Handlers first, before DDS is even imported (seconds on a loaded machine): a Ctrl-C
        # from here on always ends in a finished bag, never in a KeyboardInterrupt.
        old = self._install_signals() if handle_signals else {}
        try:
            self.writer = writer = BagWriter(self.output_dir, **self._writer_args)
            thread = threading.Thread(target=self._write_loop, args=(writer,),
                                      name='bag-writer', daemon=True)
            thread.start()
            try:
                discovery = None
                if not self._stop.is_set():
                    from .. import dds
                    discovery = dds.Discovery()
                deadline = None if duration is None else time.monotonic() + duration
                while discovery is not None and not self._stop.is_set():
                    self._subscribe_new(discovery, writer)
                    wait = self.discovery_interval
                    if deadline is not None:
                        wait = min(wait, deadline - time.monotonic())
                        if wait <= 0:
                            break
                    self._stop.wait(wait)
            finally:
                self._finish(thread, writer)
        finally:
            for sig, handler in old.items():
                signal.signal(sig, handler)
        if self._error is not None:
            if self.metadata is None:  # the bag could not be finished (disk full, I/O error)
                raise BagError(f'{one_line(self._error)}; recording stopped: {self.output_dir} '
                               'keeps what was written up to its last complete chunk '
                               '(`vizzy bag reindex` finishes it once there is space)')
            raise BagError(f'{one_line(self._error)}; recording stopped, bag finished')
        counts = writer.counts
        log.info('recorded %d messages on %d topics into %s', sum(counts.values()), len(counts),
                 self.output_dir)
        return counts

    # -- discovery -----------------------------------------------------------------------------

    def _wanted(self, topic: str) -> bool:
        if topic in self.exclude:
            return False
        if self.topics is not None:
            return topic in self.topics
        return self.include_hidden or not is_hidden(topic)

    def _subscribe_new(self, discovery: Any, writer: BagWriter) -> None:
        from .. import dds
        publishers: dict[str, list[Any]] = {}
        for ep in discovery.endpoints():
            if ep.is_writer and ep.topic not in self._readers and ep.topic not in self._skipped \
                    and self._wanted(ep.topic):
                publishers.setdefault(ep.topic, []).append(ep)
        for topic, eps in sorted(publishers.items()):
            typename = eps[0].typename
            offers = [ep.qos for ep in eps]
            try:
                writer.add_topic(topic, typename, [QosProfile.from_dds(q) for q in offers])
                qos = request_qos(offers)
                self._readers[topic] = dds.RawReader(topic, typename, qos, on_data=self._on_data)
            except Exception as exc:  # noqa: BLE001 - one bad topic must not stop the recording
                log.warning('not recording %s [%s]: %s', topic, typename, exc)
                self._skipped.add(topic)
                continue
            log.info('recording %s [%s] (%s, %s)', topic, typename,
                     'reliable' if qos.reliable else 'best_effort',
                     'transient_local' if qos.transient_local else 'volatile')

    # -- data path -----------------------------------------------------------------------------

    def _on_data(self, reader: Any) -> None:
        """Cyclone listener thread: take and enqueue only (the writer thread does the rest)."""
        try:
            now = time.time_ns()
            while True:
                samples = reader.take(_TAKE)
                for data, source_ns in samples:
                    self._queue.put((reader.topic_name, data, now, source_ns or now))
                if len(samples) < _TAKE:
                    return
        except Exception as exc:  # noqa: BLE001 - never raise into Cyclone's thread
            log.error('taking from %s failed: %s', reader.topic_name, exc)

    def _write_loop(self, writer: BagWriter) -> None:
        while True:
            item: tuple[str, bytes, int, int] | tuple[()] | None
            try:
                item = self._queue.get(timeout=0.2)
            except queue.Empty:
                item = ()  # idle: still write out a partly filled chunk every flush_interval
            if item is None:
                return
            try:
                if item:
                    writer.write(*item)
                else:
                    writer.maybe_flush()
            except Exception as exc:  # noqa: BLE001 - e.g. disk full: stop, finish what we have
                self._error = exc
                self._stop.set()
                return

    def _finish(self, thread: threading.Thread, writer: BagWriter) -> None:
        for reader in self._readers.values():
            from .. import dds  # imported already: there are readers
            self._on_data(reader)  # what arrived but was not taken yet
            dds.delete(reader)
        self._queue.put(None)
        thread.join()
        try:
            self.metadata = writer.close()
        except BagError as exc:
            self._error = self._error or exc

    def _install_signals(self) -> dict[int, Any]:
        if threading.current_thread() is not threading.main_thread():
            return {}
        return {sig: signal.signal(sig, self.handle_signal)
                for sig in (signal.SIGINT, signal.SIGTERM)}
