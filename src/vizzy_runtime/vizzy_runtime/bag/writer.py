"""BagWriter: a rosbag2 (Jazzy) bag directory with one chunked, zstd-compressed MCAP file."""

from __future__ import annotations

import contextlib
import fcntl
import os
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from types import TracebackType

from mcap.writer import CompressionType, Writer

from .. import msgs
from .common import (
    INFINITE_NS,
    BagError,
    BagMetadata,
    FileInfo,
    QosProfile,
    TopicInfo,
    dump_qos_profiles,
    dump_yaml,
)

_COMPRESSION = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE, '': CompressionType.NONE}
LIBRARY = f'vizzy_runtime.bag (mcap-python {version("mcap")})'


@dataclass
class _Topic:
    info: TopicInfo
    channel_id: int
    count: int = 0


def type_info(typename: str) -> tuple[str, str]:
    """(ros2msg definition, RIHS01 hash) of a type known to the bundled typestore."""
    try:
        return (msgs.message_definition(typename),
                msgs.registry().store.hash_rihs01(msgs.normalize_type_name(typename)))
    except Exception:  # noqa: BLE001 - rosbags raises TypesysError or KeyError
        raise BagError(f'unknown message type {typename!r} (not in the bundled typestore)') \
            from None


class BagWriter:
    """Write a rosbag2 bag that `ros2 bag` (Jazzy) and rosbags read.

    Layout: `<bag_dir>/<bag_dir name>_0.mcap` (profile ros2, ros2msg schemas, cdr channels
    with offered_qos_profiles and topic_type_hash metadata, chunked and indexed) and, on close,
    `metadata.yaml` (version 9). Chunks are written out every `chunk_size` bytes or
    `flush_interval` seconds, so a killed writer loses at most that much (see BagReader).

    Args:
        bag_dir: directory to create; it must not exist or be empty.
        chunk_size: uncompressed bytes per MCAP chunk.
        flush_interval: seconds after which a partly filled chunk is written out anyway.
        compression: chunk compression, 'zstd', 'lz4' or 'none'.
        custom_data: metadata.yaml custom_data (str -> str).

    Thread-safe; use as a context manager or call close().
    """

    def __init__(self, bag_dir: str | os.PathLike[str], *, chunk_size: int = 1 << 20,
                 flush_interval: float = 1.0, compression: str = 'zstd',
                 custom_data: dict[str, str] | None = None) -> None:
        self.path = Path(bag_dir)
        if compression not in _COMPRESSION:
            raise BagError(f'{self.path}: unknown compression {compression!r} (zstd, lz4, none)')
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            raise BagError(f'{self.path}: already exists, not overwriting')
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            self.file_path = self.path / f'{self.path.name}_0.mcap'
            self._file = open(self.file_path, 'xb')  # noqa: SIM115 - kept open until close()
        except OSError as exc:
            raise BagError(f'{self.path}: cannot create bag: {exc.strerror}') from None
        # The lock tells readers the file is still being written; the kernel drops it even on
        # SIGKILL, which is how a reader tells a live recording from a killed one.
        fcntl.flock(self._file.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        self._mcap = Writer(self._file, chunk_size=chunk_size,
                            compression=_COMPRESSION[compression])
        self._mcap.start(profile='ros2', library=LIBRARY)
        self._file.flush()  # the header on disk: even an immediately killed recording is an MCAP
        self.flush_interval = flush_interval
        self.custom_data = dict(custom_data or {})
        self._lock = threading.Lock()
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self._start, self._end = INFINITE_NS, 0
        self._last_flush = time.monotonic()
        self._closed = False

    # -- topics & messages ---------------------------------------------------------------------

    def add_topic(self, topic: str, typename: str,
                  offered_qos_profiles: Iterable[QosProfile] = (), *,
                  serialization_format: str = 'cdr', msgdef: str | None = None,
                  type_hash: str | None = None) -> None:
        """Declare a topic before writing to it (again with the same type: no-op).

        Args:
            topic: fully qualified topic name.
            typename: 'pkg/msg/Type'.
            offered_qos_profiles: the publishers' QoS, replayed by Player.
            serialization_format: 'cdr' for ROS 2.
            msgdef, type_hash: ros2msg definition and RIHS01 hash; default: from the bundled
                typestore (BagError if the type is unknown there).
        """
        try:
            typename = msgs.normalize_type_name(typename)
        except ValueError as exc:
            raise BagError(f'{self.path}: topic {topic}: {exc}') from None
        with self._lock:
            self._check_open()
            known = self._topics.get(topic)
            if known is not None:
                if known.info.type != typename:
                    raise BagError(f'{self.path}: topic {topic} already recorded as '
                                   f'{known.info.type}, not {typename}')
                return
            if msgdef is None or type_hash is None:
                try:
                    own_def, own_hash = type_info(typename)
                except BagError as exc:
                    raise BagError(f'{self.path}: topic {topic}: {exc}') from None
                msgdef = own_def if msgdef is None else msgdef
                type_hash = own_hash if type_hash is None else type_hash
            profiles = tuple(offered_qos_profiles)
            schema_id = self._schemas.get(typename)
            if schema_id is None:
                encoding = 'ros2idl' if msgdef.startswith('=' * 80 + '\nIDL: ') else 'ros2msg'
                schema_id = self._mcap.register_schema(typename, encoding, msgdef.encode())
                self._schemas[typename] = schema_id
            channel_id = self._mcap.register_channel(
                topic, serialization_format, schema_id,
                {'offered_qos_profiles': dump_qos_profiles(profiles),
                 'topic_type_hash': type_hash})
            self._topics[topic] = _Topic(TopicInfo(topic, typename, serialization_format,
                                                   profiles, type_hash), channel_id)

    def write(self, topic: str, data: bytes | bytearray | memoryview, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Append one message (CDR bytes, stored verbatim) to an added topic.

        Args:
            topic: a topic given to add_topic.
            data: serialized message.
            log_time_ns: receive time (rosbag2's recv_timestamp; playback is timed by it).
            publish_time_ns: send time (DDS source timestamp); default log_time_ns.
        """
        with self._lock:
            self._check_open()
            entry = self._topics.get(topic)
            if entry is None:
                raise BagError(f'{self.path}: write to {topic} before add_topic')
            entry.count += 1
            try:
                self._mcap.add_message(entry.channel_id, log_time_ns, bytes(data),
                                       log_time_ns if publish_time_ns is None else publish_time_ns,
                                       sequence=entry.count)
            except OSError as exc:
                raise BagError(f'{self.file_path}: write failed: {exc.strerror}') from None
            self._start = min(self._start, log_time_ns)
            self._end = max(self._end, log_time_ns)
            if time.monotonic() - self._last_flush >= self.flush_interval:
                self._flush_locked()

    def flush(self) -> None:
        """Write out the chunk in progress (no-op when empty), so a crash cannot lose it."""
        with self._lock:
            if not self._closed:
                self._flush_locked()

    def maybe_flush(self) -> None:
        """flush() if flush_interval has passed since the last one (call when idle)."""
        with self._lock:
            if not self._closed and time.monotonic() - self._last_flush >= self.flush_interval:
                self._flush_locked()

    def _flush_locked(self) -> None:
        try:
            self._mcap.flush()
        except OSError as exc:
            raise BagError(f'{self.file_path}: write failed: {exc.strerror}') from None
        self._last_flush = time.monotonic()

    def _check_open(self) -> None:
        if self._closed:
            raise BagError(f'{self.path}: bag writer is closed')

    # -- state ---------------------------------------------------------------------------------

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per topic."""
        with self._lock:
            return {name: t.count for name, t in self._topics.items()}

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    def metadata(self) -> BagMetadata:
        """metadata.yaml content for what has been written so far."""
        with self._lock:
            return self._metadata_locked()

    def _metadata_locked(self) -> BagMetadata:
        count = sum(t.count for t in self._topics.values())
        file_info = FileInfo(self.file_path.name, self._start if count else INFINITE_NS,
                             self._end - self._start if count else 0, count)
        topics = [TopicInfo(t.info.name, t.info.type, t.info.serialization_format,
                            t.info.offered_qos_profiles, t.info.type_description_hash, t.count)
                  for t in self._topics.values()]
        return BagMetadata('mcap', [file_info], topics, custom_data=self.custom_data)

    def close(self) -> BagMetadata:
        """Finish the MCAP (last chunk, summary, index, footer) and write metadata.yaml."""
        with self._lock:
            if self._closed:
                return self._metadata_locked()
            self._closed = True
            meta = self._metadata_locked()
            try:
                self._mcap.flush()
                # rosbag2_storage_mcap stores the bag metadata in the file too (update_metadata).
                self._mcap.add_metadata('rosbag2',
                                        {'serialized_metadata': dump_yaml(meta.to_dict())})
                self._mcap.finish()
                self._file.flush()
                os.fsync(self._file.fileno())
            except OSError as exc:
                raise BagError(f'{self.file_path}: finishing failed: {exc.strerror}') from None
            finally:
                # the finishing error above says it; the buffered tail is lost
                with contextlib.suppress(OSError):
                    self._file.close()
            meta.write(self.path)
            return meta

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        # Finish the file even after an error: what was written stays readable.
        self.close()

