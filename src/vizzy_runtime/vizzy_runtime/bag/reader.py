"""BagReader: rosbag2 bag directories (MCAP; sqlite3 through rosbags), including killed recordings.

A recording killed with SIGKILL leaves an MCAP file without summary and footer, often ending in
half a chunk, and no metadata.yaml. Such a file is scanned record by record up to the last
complete one, rewritten with a summary (atomically, through mcap's Writer) and metadata.yaml is
rebuilt from the files, as `ros2 bag reindex` does; a one-line warning says what was recovered.
A file still locked by a live BagWriter is only read, never rewritten.
"""

from __future__ import annotations

import dataclasses
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
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Header, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import breakup_chunk
from mcap.summary import Summary
from mcap.writer import CompressionType, Writer

from .chunks import (
    CHUNK_ERRORS,
    DECODE_ERRORS,
    ChunkCheck,
    CorruptChunk,
    check_chunks,
    chunk_indexes,
    decode_chunk,
    error_text,
    indexed_messages,
    read_summary,
)
from .common import (
    INFINITE_NS,
    MCAP_MAGIC,
    METADATA_FILE,
    BagError,
    BagMessage,
    BagMetadata,
    FileInfo,
    TopicInfo,
    dump_yaml,
    mcap_has_footer,
    one_line,
    parse_qos_profiles,
)

log = logging.getLogger('vizzy_runtime.bag')

_DECODE_ERRORS = DECODE_ERRORS
_READ_ERRORS: tuple[type[BaseException], ...] = (OSError, *_DECODE_ERRORS)
_COMPRESSION = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4}


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
    chunks: int = 0   # complete chunks read
    corrupt: list[CorruptChunk] = field(default_factory=list)  # complete chunks skipped
    problem: str = ''  # why the scan stopped early ('' when it did not)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())


def _scan(path: Path, scan: _Scan, on_corrupt: Callable[[CorruptChunk], None] | None = None
          ) -> Iterator[Schema | Channel | Message | Metadata]:
    """Yield the data records of an MCAP file in file order (a chunk's messages sorted by log
    time), stopping cleanly before the first record that is cut short or does not decode.
    A complete chunk that does not decompress, fails its CRC or does not parse is skipped
    instead (its record length says where the next record starts): it goes to scan.corrupt
    and on_corrupt, with the messages its message index records (which follow it) list."""
    skipped: CorruptChunk | None = None  # the chunk just skipped, its message indexes to count

    def report_skipped() -> None:
        nonlocal skipped
        if skipped is not None:
            scan.corrupt.append(skipped)
            if on_corrupt is not None:
                on_corrupt(skipped)
            skipped = None

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
                report_skipped()
                return
            opcode, length = struct.unpack('<BQ', head)
            name = Opcode(opcode).name.lower() if opcode in Opcode._value2member_map_ else \
                f'opcode {opcode:#x}'
            if pos + 9 + length > size:
                scan.problem = (f'incomplete {name} record at byte {pos}: '
                                f'{size - pos - 9} of {length} bytes')
                report_skipped()
                return
            body = f.read(length)
            if opcode == Opcode.MESSAGE_INDEX and skipped is not None:
                try:
                    listed = len(MessageIndex.read(ReadDataStream(io.BytesIO(body))).records)
                    skipped = dataclasses.replace(skipped, messages=(skipped.messages or 0)
                                                  + listed)
                except _DECODE_ERRORS:
                    pass
            else:
                report_skipped()
            try:
                records = _parse(opcode, body)
            except CHUNK_ERRORS as exc:
                if opcode != Opcode.CHUNK:
                    scan.problem = f'corrupt {name} record at byte {pos}: {one_line(exc)}'
                    return
                number = scan.chunks + len(scan.corrupt) + 1
                skipped = CorruptChunk(path, number, 0, pos, None, error_text(exc))
                records = []
            else:
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
                report_skipped()
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


def _rewrite(path: Path, copy: Callable[[io.BufferedWriter], None]) -> None:
    """Replace an MCAP file with what copy() writes to a new one: atomically, only once the new
    file is on disk, never while a live BagWriter holds the file."""
    tmp = path.with_name(path.name + '.recovering')
    with open(path, 'rb') as lock_holder:
        if not _try_lock(lock_holder):
            raise _CannotRepair(path, 'still being recorded (locked by a live writer)')
        try:
            with open(tmp, 'wb') as out:
                copy(out)
                out.flush()
                os.fsync(out.fileno())
            os.replace(tmp, path)
        except OSError as exc:
            raise _CannotRepair(path, f'cannot rewrite it: {exc.strerror}') from None
        finally:
            tmp.unlink(missing_ok=True)


def _repair(path: Path) -> _Scan:
    """Rewrite an unfinished MCAP file (or one whose summary is damaged) with everything its
    complete, intact records hold, then a summary and footer."""
    scan = _Scan()
    _rewrite(path, lambda out: _copy_records(path, scan, out))
    return scan


def _drop_chunks(path: Path, summary: Summary, check: ChunkCheck,
                 old: BagMetadata | None) -> None:
    """Rewrite a finished MCAP file without its corrupt chunks: the same header, schemas,
    channels (all of them, so no topic disappears), the good chunks' messages with the same
    chunk boundaries and compression, attachments and metadata records. rosbag2's own
    'rosbag2' metadata record is written anew with the counts that are left."""
    bad = {c.offset for c in check.corrupt or ()}
    indexes = chunk_indexes(summary)
    good = [ci for ci in indexes if ci.chunk_start_offset not in bad]
    compression = _COMPRESSION.get(good[0].compression if good else indexes[0].compression,
                                   CompressionType.NONE)

    def copy(out: io.BufferedWriter) -> None:
        with open(path, 'rb') as src:
            reader = make_reader(src)
            try:
                header = reader.get_header()
            except _DECODE_ERRORS:
                header = Header('ros2', '')
            try:
                records = list(reader.iter_metadata())
                attachments = list(reader.iter_attachments())
            except _DECODE_ERRORS as exc:
                log.warning('%s: metadata or attachment records unreadable (%s); not kept',
                            path, error_text(exc))
                records, attachments = [], []
            writer = Writer(out, compression=compression)
            writer.start(profile=header.profile, library=header.library)
            schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data)
                          for sid, s in sorted(summary.schemas.items())}
            channel_ids = {cid: writer.register_channel(ch.topic, ch.message_encoding,
                                                        schema_ids.get(ch.schema_id, 0),
                                                        ch.metadata)
                           for cid, ch in sorted(summary.channels.items())}
            for ci in good:
                for rec in decode_chunk(src, ci, summary.channels):
                    if isinstance(rec, Message):
                        writer.add_message(channel_ids[rec.channel_id], rec.log_time, rec.data,
                                           rec.publish_time, rec.sequence)
                writer.flush()  # ends the chunk where the original ended
            for a in attachments:
                writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
            for rec in records:
                if rec.name != 'rosbag2':
                    writer.add_metadata(rec.name, rec.metadata)
            if any(rec.name == 'rosbag2' for rec in records):
                counts = check.counts or {}
                count = sum(counts.values())
                meta = BagMetadata(
                    'mcap', [FileInfo(path.name, check.start if count else INFINITE_NS,
                                      check.end - check.start if count else 0, count)],
                    _topics_and_stats(summary.schemas, summary.channels, counts))
                if old is not None:
                    meta.custom_data, meta.ros_distro = old.custom_data, old.ros_distro
                writer.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(meta.to_dict())})
            writer.finish()

    try:
        _rewrite(path, copy)
    except CHUNK_ERRORS as exc:  # a chunk checked a moment ago no longer reads
        raise BagError(f'{path}: changed while being reindexed: {error_text(exc)}') from None


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


def lost_messages(corrupt: Iterable[CorruptChunk]) -> str:
    """'100 messages', '100+ messages' (some chunk's count unknown) or '? messages'."""
    corrupt = list(corrupt)
    known = sum(c.messages or 0 for c in corrupt)
    if all(c.messages is None for c in corrupt):
        return '? messages'
    return f'{known}{"+" if any(c.messages is None for c in corrupt) else ""} messages'


def dropped_text(corrupt: list[CorruptChunk], verb: str = 'dropped', listed: int = 3) -> str:
    """'dropped 1 corrupt chunk with 100 messages (chunk 5 of 10 (byte ...): ZstdError: ...)'"""
    parts = [c.describe().split(' ', 1)[1] for c in corrupt[:listed]]
    if len(corrupt) > listed:
        parts.append(f'and {len(corrupt) - listed} more')
    plural = 's' if len(corrupt) != 1 else ''
    return (f'{verb} {len(corrupt)} corrupt chunk{plural} with {lost_messages(corrupt)} '
            f'({"; ".join(parts)})')


@dataclass
class FileCheck:
    """What decoding every chunk of one .mcap file found (`vizzy bag info --check`)."""

    file: Path
    chunks: int                 # chunks in the file, good and corrupt
    messages: int               # messages that read
    corrupt: list[CorruptChunk]
    problem: str = ''           # anything else: unfinished, damaged summary ('' when none)


def check_file(file: Path) -> FileCheck:
    """Decode every chunk of an .mcap file and check its CRC; never writes. Raises BagError
    only when the file cannot be read at all."""
    problem = ''
    try:
        if mcap_has_footer(file):
            try:
                with open(file, 'rb') as f:
                    summary = read_summary(f)
                    if summary is not None and summary.chunk_indexes:
                        chk = check_chunks(file, f, summary)
                        return FileCheck(file, chk.chunks, chk.messages, chk.corrupt or [])
            except _DECODE_ERRORS as exc:
                problem = f'damaged summary ({error_text(exc)}; `vizzy bag reindex` rebuilds it)'
        else:
            problem = 'not finished (a killed recording; `vizzy bag reindex` finishes it)'
        scan = _Scan()
        for _ in _scan(file, scan):
            pass
    except OSError as exc:
        raise BagError(f'{file}: cannot read: {exc.strerror}') from None
    if scan.problem:
        problem = f'{problem}; {scan.problem}' if problem else scan.problem
    return FileCheck(file, scan.chunks + len(scan.corrupt), scan.message_count, scan.corrupt,
                     problem)


def _reindex_finished(file: Path, old: BagMetadata | None) -> list[CorruptChunk]:
    """Decode every chunk of a finished file; rewrite it without the corrupt ones (or from its
    data section when its summary is damaged). Returns the chunks dropped."""
    try:
        with open(file, 'rb') as f:
            summary = read_summary(f)
            chk = check_chunks(file, f, summary) if summary and summary.chunk_indexes else None
    except OSError as exc:
        raise BagError(f'{file}: cannot read: {exc.strerror}') from None
    except _DECODE_ERRORS as exc:
        scan = _repair(file)
        log.warning('%s: damaged summary (%s); rebuilt it from the data section: %d messages in '
                    '%d chunks%s', file, error_text(exc), scan.message_count, scan.chunks,
                    '; ' + dropped_text(scan.corrupt) if scan.corrupt else '')
        return scan.corrupt
    if chk is None:  # no chunk index (summary-less or unchunked): the data section says
        scan = _Scan()
        for _ in _scan(file, scan):
            pass
        if not scan.corrupt:
            return []
        scan = _repair(file)
    else:
        if not chk.corrupt:
            return []
        assert summary is not None
        _drop_chunks(file, summary, chk, old)
        scan = _Scan(chunks=chk.chunks - len(chk.corrupt), corrupt=chk.corrupt,
                     counts=chk.counts or {})
    log.warning('%s: %s; kept %d messages in %d chunks', file, dropped_text(scan.corrupt),
                scan.message_count, scan.chunks)
    return scan.corrupt


@dataclass
class Reindexed:
    """What reindex_bag() did."""

    metadata: BagMetadata           # the new metadata.yaml
    dropped: list[CorruptChunk]     # corrupt chunks dropped (their messages are lost)
    recovered: list[Path]           # unfinished files finished (killed recordings)


def reindex_bag(bag_dir: str | os.PathLike[str], *, check: bool = True) -> Reindexed:
    """`ros2 bag reindex`: rebuild metadata.yaml from the .mcap files, after finishing
    unfinished files (killed recordings) and, with check, decoding every chunk of every file
    and rewriting the files that hold corrupt chunks without them (every good message, every
    topic, the metadata records kept).

    Logs one warning per file it rewrote (what it kept, which chunks it dropped with how many
    messages). Raises BagError if the directory holds no .mcap file, a file is still being
    recorded or cannot be rewritten.
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
    dropped: list[CorruptChunk] = []
    recovered: list[Path] = []
    for file in files:
        if mcap_has_footer(file):
            if check:
                dropped += _reindex_finished(file, old)
            continue
        scan = _repair(file)
        recovered.append(file)
        dropped += scan.corrupt
        why = f' ({scan.problem})' if scan.problem else ''
        lost = f'; {dropped_text(scan.corrupt)}' if scan.corrupt else ''
        log.warning('%s: recording was not closed; recovered %d messages from %d complete '
                    'chunks%s%s; rebuilt %s', file, scan.message_count, scan.chunks, why, lost,
                    METADATA_FILE)
    summaries = [_summarize(f) for f in files]
    meta = BagMetadata('mcap', [s[1] for s in summaries], _merge_topics(s[0] for s in summaries))
    if old is not None:
        meta.custom_data, meta.ros_distro = old.custom_data, old.ros_distro or meta.ros_distro
    meta.write(path)
    return Reindexed(meta, dropped, recovered)


def reindex(bag_dir: str | os.PathLike[str]) -> BagMetadata:
    """reindex_bag(bag_dir).metadata: the bag's new metadata.yaml content."""
    return reindex_bag(bag_dir).metadata


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
        self._corrupt: dict[tuple[Path, int], CorruptChunk] = {}  # skipped while reading
        self._warned: set[Path] = set()  # files whose damaged summary was reported
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
            try:  # only finishes killed recordings: a corrupt chunk is skipped when read
                return reindex_bag(self.path, check=False).metadata
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
            summary = None
            if file not in self._scanned and mcap_has_footer(file):
                with open(file, 'rb') as f:
                    try:
                        summary = read_summary(f)
                    except _DECODE_ERRORS as exc:  # the data section may well be intact
                        self._warn_once(file, f'{file}: damaged summary ({error_text(exc)}); '
                                              'reading its data section instead')
            if summary is None or not summary.chunk_indexes:  # unfinished, or no chunk index
                scan = _Scan()
                for rec in _scan(file, scan, self._skip_corrupt):
                    if isinstance(rec, Message) and lo <= rec.log_time < hi:
                        ch = scan.channels[rec.channel_id]
                        if wanted is None or ch.topic in wanted:
                            yield BagMessage(ch.topic, self._type_of(ch, scan.schemas), rec.data,
                                             rec.log_time, rec.publish_time)
                return
            ids = None if wanted is None else {cid for cid, ch in summary.channels.items()
                                               if ch.topic in wanted}
            with open(file, 'rb') as f:
                for ch, msg in indexed_messages(file, f, summary, ids, lo, hi,
                                                self._skip_corrupt):
                    yield BagMessage(ch.topic, self._type_of(ch, summary.schemas), msg.data,
                                     msg.log_time, msg.publish_time)
        except BagError:
            raise
        except OSError as exc:
            raise BagError(f'{file}: cannot read: {exc.strerror}') from None
        except _DECODE_ERRORS as exc:
            raise BagError(f'{file}: corrupt MCAP data ({error_text(exc)})') from None

    @property
    def corrupt_chunks(self) -> list[CorruptChunk]:
        """Chunks that did not decompress or failed their CRC while reading: their messages
        were skipped (`vizzy bag reindex` drops them from the files)."""
        return list(self._corrupt.values())

    def _skip_corrupt(self, chunk: CorruptChunk) -> None:
        key = (chunk.file, chunk.offset)
        if key in self._corrupt:  # read again (a loop): said once
            return
        self._corrupt[key] = chunk
        log.warning('skipped corrupt chunk %s; reading on (`vizzy bag reindex` drops it)',
                    chunk.describe())

    def _warn_once(self, file: Path, text: str) -> None:
        if file not in self._warned:
            self._warned.add(file)
            log.warning('%s', text)

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
