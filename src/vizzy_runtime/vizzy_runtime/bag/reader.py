"""BagReader: rosbag2 bag directories (MCAP; sqlite3 through rosbags), including killed recordings.

A recording killed with SIGKILL leaves an MCAP file without summary and footer, often ending in
half a chunk, and no metadata.yaml. Such a file is scanned record by record up to the last
complete one, rewritten with a summary (atomically, through mcap's Writer) and metadata.yaml is
rebuilt from the files, as `ros2 bag reindex` does; a one-line warning says what was recovered.
A file still locked by a live BagWriter is only read, never rewritten.
"""

from __future__ import annotations

import fcntl
import heapq
import io
import logging
import os
import re
import struct
from collections.abc import Callable, Collection, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType, Writer

from .common import (
    INFINITE_NS,
    MCAP_MAGIC,
    METADATA_FILE,
    BagError,
    BagMessage,
    BagMetadata,
    FileInfo,
    TopicInfo,
    mcap_has_footer,
    one_line,
    parse_qos_profiles,
)

log = logging.getLogger('vizzy_runtime.bag')

# What a damaged file can raise from mcap / zstandard / lz4 / struct while being decoded.
_DECODE_ERRORS: tuple[type[BaseException], ...] = (McapError, struct.error, ValueError,
                                                    KeyError, EOFError, RuntimeError)
try:
    import zstandard
    _DECODE_ERRORS += (zstandard.ZstdError,)
except ImportError:  # pragma: no cover - zstandard is a pinned dependency
    pass
_READ_ERRORS: tuple[type[BaseException], ...] = (OSError, *_DECODE_ERRORS)


# --- sequential scan (files without summary) ----------------------------------------------------

@dataclass
class _Scan:
    """What a record-by-record scan of an MCAP file found."""

    header: Header | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start: int = INFINITE_NS
    end: int = 0
    chunks: int = 0
    problem: str = ''  # why the scan stopped early ('' when it did not)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())


def _scan(path: Path, scan: _Scan) -> Iterator[Schema | Channel | Message | Metadata]:
    """Yield the data records of an MCAP file in file order (a chunk's messages sorted by log
    time), stopping cleanly before the first record that is cut short or does not decode."""
    with open(path, 'rb') as f:
        size = os.fstat(f.fileno()).st_size
        magic = f.read(8)
        if len(magic) < 8 and MCAP_MAGIC.startswith(magic):
            scan.problem = 'file ends inside the magic'  # killed before anything was flushed
            return
        if magic != MCAP_MAGIC:
            raise BagError(f'{path}: not an MCAP file (bad magic)')
        pos = 8
        while True:
            head = f.read(9)
            if len(head) < 9:  # at a record boundary nothing is lost; else a header was cut
                scan.problem = f'incomplete record header at byte {pos}' if head else ''
                return
            opcode, length = struct.unpack('<BQ', head)
            name = Opcode(opcode).name.lower() if opcode in Opcode._value2member_map_ else \
                f'opcode {opcode:#x}'
            if pos + 9 + length > size:
                scan.problem = (f'incomplete {name} record at byte {pos}: '
                                f'{size - pos - 9} of {length} bytes')
                return
            body = f.read(length)
            try:
                records = _parse(opcode, body)
            except _DECODE_ERRORS as exc:
                scan.problem = f'corrupt {name} record at byte {pos}: {one_line(exc)}'
                return
            if opcode == Opcode.CHUNK:
                scan.chunks += 1
            for rec in records:
                if isinstance(rec, Header):
                    scan.header = rec
                    continue
                if isinstance(rec, Schema):
                    scan.schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    scan.channels[rec.id] = rec
                elif isinstance(rec, Message):
                    if rec.channel_id not in scan.channels:
                        continue  # its channel record was lost: the data cannot be interpreted
                    scan.counts[rec.channel_id] = scan.counts.get(rec.channel_id, 0) + 1
                    scan.start = min(scan.start, rec.log_time)
                    scan.end = max(scan.end, rec.log_time)
                yield rec
            pos += 9 + length
            if opcode in (Opcode.DATA_END, Opcode.FOOTER):  # the data section is complete
                return


def _parse(opcode: int, body: bytes) -> list[Any]:
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.CHUNK:
        records = breakup_chunk(Chunk.read(stream), validate_crc=True)
        messages = sorted((r for r in records if isinstance(r, Message)), key=lambda m: m.log_time)
        return [r for r in records if not isinstance(r, Message)] + messages
    if opcode == Opcode.MESSAGE:
        return [Message.read(stream, len(body))]
    readers: dict[int, Callable[[ReadDataStream], Any]] = {
        Opcode.HEADER: Header.read, Opcode.SCHEMA: Schema.read, Opcode.CHANNEL: Channel.read,
        Opcode.METADATA: Metadata.read}
    return [readers[opcode](stream)] if opcode in readers else []


def _try_lock(f: io.BufferedReader | io.BufferedRandom) -> bool:
    """Take the lock a BagWriter holds while writing; False if a live writer has it."""
    try:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False


class _CannotRepair(BagError):
    """An unfinished file that may not or could not be rewritten (it is then only scanned)."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f'{path}: {reason}')
        self.reason = reason


def _repair(path: Path) -> _Scan:
    """Rewrite an unfinished MCAP file with everything its complete records hold, then a summary
    and footer. The original is replaced atomically, only once the new file is on disk."""
    tmp = path.with_name(path.name + '.recovering')
    with open(path, 'rb') as lock_holder:
        if not _try_lock(lock_holder):
            raise _CannotRepair(path, 'still being recorded (locked by a live writer)')
        scan = _Scan()
        try:
            with open(tmp, 'wb') as out:
                _copy_records(path, scan, out)
                out.flush()
                os.fsync(out.fileno())
            os.replace(tmp, path)
        except OSError as exc:
            raise _CannotRepair(path, f'cannot rewrite it: {exc.strerror}') from None
        finally:
            tmp.unlink(missing_ok=True)
        return scan


def _copy_records(path: Path, scan: _Scan, out: io.BufferedWriter) -> None:
    writer = Writer(out, compression=CompressionType.ZSTD)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    started = False
    for rec in _scan(path, scan):
        if not started:  # the original header comes first (if the file has one)
            header = scan.header or Header('ros2', '')
            writer.start(profile=header.profile, library=header.library)
            started = True
        if isinstance(rec, Schema):
            schema_ids[rec.id] = writer.register_schema(rec.name, rec.encoding, rec.data)
        elif isinstance(rec, Channel):
            channel_ids[rec.id] = writer.register_channel(
                rec.topic, rec.message_encoding, schema_ids.get(rec.schema_id, 0), rec.metadata)
        elif isinstance(rec, Message) and rec.channel_id in channel_ids:
            writer.add_message(channel_ids[rec.channel_id], rec.log_time, rec.data,
                               rec.publish_time, rec.sequence)
        elif isinstance(rec, Metadata):
            writer.add_metadata(rec.name, rec.metadata)
    if not started:
        writer.start(profile='ros2', library='')
    writer.finish()


# --- metadata from the files themselves ---------------------------------------------------------

_NUMBERED = re.compile(r'_(\d+)\.mcap$')


def _mcap_files(bag_dir: Path) -> list[Path]:
    """The .mcap files of a bag, in split order (<name>_0.mcap, <name>_1.mcap, ...)."""
    def key(p: Path) -> tuple[int, str]:
        m = _NUMBERED.search(p.name)
        return (int(m.group(1)) if m else -1, p.name)
    return sorted((p for p in bag_dir.glob('*.mcap') if p.is_file()), key=key)


def _topics_and_stats(schemas: dict[int, Schema], channels: dict[int, Channel],
                      counts: dict[int, int]) -> list[TopicInfo]:
    topics = []
    for cid, ch in channels.items():
        schema = schemas.get(ch.schema_id)
        topics.append(TopicInfo(
            name=ch.topic, type=schema.name if schema else '',
            serialization_format=ch.message_encoding,
            offered_qos_profiles=tuple(parse_qos_profiles(ch.metadata.get('offered_qos_profiles',
                                                                          ''))),
            type_description_hash=ch.metadata.get('topic_type_hash', ''),
            message_count=counts.get(cid, 0)))
    return topics


def _summarize(path: Path) -> tuple[list[TopicInfo], FileInfo]:
    """Topics and file entry of a finished MCAP file, from its summary section."""
    try:
        with open(path, 'rb') as f:
            summary = make_reader(f).get_summary()
            if summary is None or summary.statistics is None:
                scan = _Scan()
                for _ in _scan(path, scan):
                    pass
                schemas, channels, counts = scan.schemas, scan.channels, scan.counts
                start, end = scan.start, scan.end
            else:
                stats = summary.statistics
                schemas, channels = summary.schemas, summary.channels
                counts = dict(stats.channel_message_counts)
                start, end = stats.message_start_time, stats.message_end_time
    except _READ_ERRORS as exc:
        raise BagError(f'{path}: unreadable MCAP summary: {one_line(exc)}') from None
    count = sum(counts.values())
    return (_topics_and_stats(schemas, channels, counts),
            FileInfo(path.name, start if count else INFINITE_NS, end - start if count else 0,
                     count))


def _merge_topics(per_file: Iterable[list[TopicInfo]]) -> list[TopicInfo]:
    merged: dict[str, TopicInfo] = {}
    for topics in per_file:
        for t in topics:
            old = merged.get(t.name)
            merged[t.name] = t if old is None else TopicInfo(
                old.name, old.type, old.serialization_format,
                old.offered_qos_profiles or t.offered_qos_profiles,
                old.type_description_hash or t.type_description_hash,
                old.message_count + t.message_count)
    return list(merged.values())


def reindex(bag_dir: str | os.PathLike[str]) -> BagMetadata:
    """Finish unfinished .mcap files of a bag and rebuild its metadata.yaml (`ros2 bag reindex`).

    Args:
        bag_dir: the bag directory.

    Returns the new metadata. Logs one warning per repaired file (file, messages recovered).
    Raises BagError if the directory holds no .mcap file, a file is still being recorded or
    cannot be rewritten.
    """
    path = Path(bag_dir)
    if not path.is_dir():
        raise BagError(f'{path}: no such bag directory')
    files = _mcap_files(path)
    if not files:
        raise BagError(f'{path}: not a rosbag2 bag (no {METADATA_FILE}, no .mcap file)')
    old: BagMetadata | None = None
    if (path / METADATA_FILE).exists():
        try:
            old = BagMetadata.load(path / METADATA_FILE)
        except BagError:
            old = None  # rebuilt below from the files
    for file in files:
        if mcap_has_footer(file):
            continue
        scan = _repair(file)
        why = f' ({scan.problem})' if scan.problem else ''
        log.warning('%s: recording was not closed; recovered %d messages from %d complete '
                    'chunks%s; rebuilt %s', file, scan.message_count, scan.chunks, why,
                    METADATA_FILE)
    summaries = [_summarize(f) for f in files]
    meta = BagMetadata('mcap', [s[1] for s in summaries], _merge_topics(s[0] for s in summaries))
    if old is not None:
        meta.custom_data, meta.ros_distro = old.custom_data, old.ros_distro or meta.ros_distro
    meta.write(path)
    return meta


# --- the reader ---------------------------------------------------------------------------------

class BagReader:
    """Read a rosbag2 bag: topics with type/count/QoS, and messages in time order.

    Args:
        bag_dir: the bag directory (metadata.yaml + storage files). A directory without
            metadata.yaml or with unfinished .mcap files (a killed recording) is repaired and
            reindexed first, with a warning; one still being recorded is read as far as flushed.
        repair: False to never write to the bag (unfinished files are then only scanned).

    Raises BagError (with the path and the problem) for anything that is not a readable bag.
    Attributes: path, metadata (BagMetadata), files (storage file paths), storage_identifier.
    """

    def __init__(self, bag_dir: str | os.PathLike[str], *, repair: bool = True) -> None:
        self.path = Path(bag_dir)
        if not self.path.exists():
            raise BagError(f'{self.path}: no such bag directory')
        if not self.path.is_dir():
            raise BagError(f'{self.path}: not a bag directory (give the folder holding '
                           f'{METADATA_FILE})')
        meta_path = self.path / METADATA_FILE
        self._scanned: set[Path] = set()  # unfinished files read by scanning only
        if meta_path.exists():
            self.metadata = BagMetadata.load(meta_path)
        else:
            self.metadata = self._reindex(repair)
        if self.metadata.compression_mode:
            raise BagError(f'{self.path}: {self.metadata.compression_mode}-compressed bags '
                           f'({self.metadata.compression_format}) are not supported')
        self.storage_identifier = self.metadata.storage_identifier
        if self.storage_identifier not in ('mcap', 'sqlite3'):
            raise BagError(f'{self.path}: unsupported storage {self.storage_identifier!r}')
        paths = self.metadata.relative_file_paths or [f.path for f in self.metadata.files]
        self.files = [self.path / p for p in paths]
        for file in self.files:
            if not file.is_file():
                raise BagError(f'{file}: missing storage file listed in {meta_path}')
        if self.storage_identifier == 'mcap' and meta_path.exists():
            unfinished = [f for f in self.files if not mcap_has_footer(f)]
            if unfinished:  # metadata.yaml exists but a file was cut short afterwards
                self.metadata = self._reindex(repair)
                self.files = [self.path / f.path for f in self.metadata.files]
        self._types = {t.name: t.type for t in self.metadata.topics}
        self._definitions: dict[str, tuple[str, str]] | None = None

    @property
    def unfinished_files(self) -> list[Path]:
        """Storage files read by scanning only: unfinished, left as they are (repair=False, a
        read-only directory, or still being recorded)."""
        return sorted(self._scanned)

    def _reindex(self, repair: bool) -> BagMetadata:
        reason = 'repair=False' if not repair else 'read-only directory'
        if repair and os.access(self.path, os.W_OK):
            try:
                return reindex(self.path)
            except _CannotRepair as exc:
                reason = exc.reason
        return self._scan_metadata(reason)

    def _scan_metadata(self, reason: str) -> BagMetadata:
        """Metadata built in memory by scanning (bag being recorded, or not writable)."""
        files = _mcap_files(self.path)
        if not files:
            raise BagError(f'{self.path}: not a rosbag2 bag (no {METADATA_FILE}, no .mcap file)')
        infos, topic_lists = [], []
        for file in files:
            if mcap_has_footer(file):
                topics, info = _summarize(file)
            else:
                scan = _Scan()
                for _ in _scan(file, scan):
                    pass
                self._scanned.add(file)
                count = scan.message_count
                topics = _topics_and_stats(scan.schemas, scan.channels, scan.counts)
                info = FileInfo(file.name, scan.start if count else INFINITE_NS,
                                scan.end - scan.start if count else 0, count)
                log.warning('%s: not finished; read %d messages from %d complete chunks '
                            'without repairing it (%s)', file, count, scan.chunks, reason)
            infos.append(info)
            topic_lists.append(topics)
        return BagMetadata('mcap', infos, _merge_topics(topic_lists))

    # -- summary -----------------------------------------------------------------------------

    @property
    def topics(self) -> dict[str, TopicInfo]:
        """Topic name -> TopicInfo (type, message_count, offered_qos_profiles, ...)."""
        return {t.name: t for t in self.metadata.topics}

    @property
    def message_count(self) -> int:
        return self.metadata.message_count

    @property
    def start_time_ns(self) -> int:
        return self.metadata.starting_time_ns

    @property
    def duration_ns(self) -> int:
        return self.metadata.duration_ns

    @property
    def end_time_ns(self) -> int:
        return self.start_time_ns + self.duration_ns if self.message_count else 0

    @property
    def size_bytes(self) -> int:
        return sum(f.stat().st_size for f in self.files)

    def definitions(self) -> dict[str, tuple[str, str]]:
        """Message type -> (schema encoding, definition text) stored in the bag."""
        if self._definitions is None:
            self._definitions = {}
            if self.storage_identifier == 'mcap':
                for file in self.files:
                    self._definitions.update(self._file_definitions(file))
            else:
                for conn in self._rosbags_connections():
                    fmt = getattr(conn.msgdef.format, 'name', 'MSG').lower()
                    self._definitions[conn.msgtype] = (f'ros2{fmt}', conn.msgdef.data)
        return self._definitions

    def _file_definitions(self, file: Path) -> dict[str, tuple[str, str]]:
        schemas: Collection[Schema]
        try:
            if file in self._scanned or not mcap_has_footer(file):
                scan = _Scan()
                for _ in _scan(file, scan):
                    pass
                schemas = scan.schemas.values()
            else:
                with open(file, 'rb') as f:
                    summary = make_reader(f).get_summary()
                schemas = summary.schemas.values() if summary else []
        except _READ_ERRORS as exc:
            raise BagError(f'{file}: unreadable MCAP schemas: {one_line(exc)}') from None
        return {s.name: (s.encoding, s.data.decode()) for s in schemas}

    # -- messages ----------------------------------------------------------------------------

    def messages(self, topics: Iterable[str] | None = None, start_ns: int | None = None,
                 stop_ns: int | None = None) -> Iterator[BagMessage]:
        """Messages in log-time order as BagMessage(topic, typename, data, log_time_ns,
        publish_time_ns); data are the stored CDR bytes.

        Args:
            topics: only these topics (default: all).
            start_ns, stop_ns: only log times in [start_ns, stop_ns).
        """
        wanted = None if topics is None else set(topics)
        if self.storage_identifier == 'sqlite3':
            yield from self._rosbags_messages(wanted, start_ns, stop_ns)
            return
        streams = [self._file_messages(f, wanted, start_ns, stop_ns) for f in self.files]
        yield from (streams[0] if len(streams) == 1 else
                    heapq.merge(*streams, key=lambda m: m.log_time_ns))

    def _file_messages(self, file: Path, wanted: set[str] | None, start_ns: int | None,
                       stop_ns: int | None) -> Iterator[BagMessage]:
        lo, hi = start_ns or 0, INFINITE_NS if stop_ns is None else stop_ns
        try:
            if file in self._scanned or not mcap_has_footer(file):
                scan = _Scan()
                for rec in _scan(file, scan):
                    if isinstance(rec, Message) and lo <= rec.log_time < hi:
                        ch = scan.channels[rec.channel_id]
                        if wanted is None or ch.topic in wanted:
                            yield BagMessage(ch.topic, self._type_of(ch, scan.schemas), rec.data,
                                             rec.log_time, rec.publish_time)
                return
            with open(file, 'rb') as f:
                reader = make_reader(f, validate_crcs=True)
                for schema, ch, msg in reader.iter_messages(
                        topics=None if wanted is None else sorted(wanted),
                        starting_at=start_ns, ending_before=stop_ns, log_time_order=True):
                    typename = schema.name if schema else self._types.get(ch.topic, '')
                    yield BagMessage(ch.topic, typename, msg.data, msg.log_time, msg.publish_time)
        except BagError:
            raise
        except OSError as exc:
            raise BagError(f'{file}: cannot read: {exc.strerror}') from None
        except _DECODE_ERRORS as exc:
            raise BagError(f'{file}: corrupt MCAP data ({type(exc).__name__}: '
                           f'{one_line(exc)})') from None

    def _type_of(self, ch: Channel, schemas: dict[int, Schema]) -> str:
        schema = schemas.get(ch.schema_id)
        return schema.name if schema else self._types.get(ch.topic, '')

    # -- sqlite3 (rosbags) -------------------------------------------------------------------

    def _rosbags_reader(self) -> Any:
        from rosbags.rosbag2 import Reader
        from rosbags.rosbag2.errors import ReaderError
        try:
            reader = Reader(self.path)
            reader.open()
        except ReaderError as exc:
            raise BagError(f'{self.path}: {one_line(exc)}') from None
        return reader

    def _rosbags_connections(self) -> list[Any]:
        reader = self._rosbags_reader()
        try:
            return list(reader.connections)
        finally:
            reader.close()

    def _rosbags_messages(self, wanted: set[str] | None, start_ns: int | None,
                          stop_ns: int | None) -> Iterator[BagMessage]:
        reader = self._rosbags_reader()
        try:
            conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
            for conn, stamp, data in reader.messages(conns, start=start_ns, stop=stop_ns):
                yield BagMessage(conn.topic, conn.msgtype, bytes(data), stamp, stamp)
        finally:
            reader.close()

    # -- context -----------------------------------------------------------------------------

    def close(self) -> None:
        """Nothing stays open between calls; kept for symmetry with BagWriter."""

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
