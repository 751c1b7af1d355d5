"""Chunk by chunk access to finished MCAP files, so that one corrupt chunk loses only itself.

mcap's SeekingReader.iter_messages raises at the first chunk whose data do not decompress or
fail their CRC, which ends a playback there. Here each chunk the summary indexes is read and
checked on its own (mcap's Chunk.read and breakup_chunk with its CRC check); a bad one is
reported as a CorruptChunk, with the messages it held counted from its message indexes, and
reading goes on with the next.
"""

from __future__ import annotations

import heapq
import io
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, ChunkIndex, Message, MessageIndex
from mcap.stream_reader import breakup_chunk
from mcap.summary import Summary

from .common import one_line

# What damaged MCAP data can raise from mcap / zstandard / lz4 / struct while being decoded.
DECODE_ERRORS: tuple[type[BaseException], ...] = (McapError, struct.error, ValueError,
                                                   KeyError, EOFError, RuntimeError)
try:
    import zstandard
    DECODE_ERRORS += (zstandard.ZstdError,)
except ImportError:  # pragma: no cover - zstandard is a pinned dependency
    pass
# A damaged size field can ask a decompressor for more memory than there is: that one chunk is
# then unreadable, not the bag.
CHUNK_ERRORS: tuple[type[BaseException], ...] = (*DECODE_ERRORS, MemoryError)
_INDEX_ERRORS: tuple[type[BaseException], ...] = (OSError, *DECODE_ERRORS)


@dataclass(frozen=True)
class CorruptChunk:
    """A chunk whose data do not decompress, fail their CRC or do not parse."""

    file: Path
    number: int            # 1-based position among the file's chunks, in file order
    chunks: int            # chunks the file has (0: not known, a file read without summary)
    offset: int            # byte offset of the chunk record in the file
    messages: int | None   # messages it held, from its message indexes (None: not known)
    reason: str

    def describe(self) -> str:
        """'bag_0.mcap chunk 5 of 10 (byte 27116, 100 messages): ZstdError: ...'"""
        of = f' of {self.chunks}' if self.chunks else ''
        held = '? messages' if self.messages is None else f'{self.messages} messages'
        return f'{self.file.name} chunk {self.number}{of} (byte {self.offset}, {held}): ' \
               f'{self.reason}'


def error_text(exc: BaseException) -> str:
    return f'{type(exc).__name__}: {one_line(exc)}'


def read_summary(f: IO[bytes]) -> Summary | None:
    """The summary of a finished file (None if it has none); DECODE_ERRORS if it is damaged."""
    return make_reader(f).get_summary()


def chunk_indexes(summary: Summary) -> list[ChunkIndex]:
    """The summary's chunk indexes in file order."""
    return sorted(summary.chunk_indexes, key=lambda ci: ci.chunk_start_offset)


def decode_chunk(f: IO[bytes], ci: ChunkIndex, channels: dict[int, Channel]) -> list[Any]:
    """The records of one indexed chunk (schemas, channels, messages in stored order), its
    uncompressed CRC checked. Raises one of CHUNK_ERRORS if it is damaged. The record is read
    by the index's offset and length, so a damaged length field does not shift what is read."""
    f.seek(ci.chunk_start_offset + 1 + 8)
    body = f.read(max(0, ci.chunk_length - 1 - 8))
    if len(body) != ci.chunk_length - 1 - 8:
        raise McapError(f'chunk cut short ({len(body)} of {ci.chunk_length - 9} bytes)')
    records = breakup_chunk(Chunk.read(ReadDataStream(io.BytesIO(body))), validate_crc=True)
    for rec in records:
        if isinstance(rec, Message) and rec.channel_id not in channels:
            raise McapError(f'message on unknown channel {rec.channel_id}')
    return records


def indexed_message_count(f: IO[bytes], ci: ChunkIndex) -> int | None:
    """How many messages a chunk holds according to its message index records (None when the
    chunk has none or they do not parse either)."""
    if not ci.message_index_offsets:
        return None
    total = 0
    try:
        for offset in ci.message_index_offsets.values():
            f.seek(offset)
            head = f.read(9)
            if len(head) < 9:
                return None
            opcode, length = struct.unpack('<BQ', head)
            if opcode != Opcode.MESSAGE_INDEX:
                return None
            stream = ReadDataStream(io.BytesIO(f.read(length)))
            total += len(MessageIndex.read(stream).records)
    except _INDEX_ERRORS:
        return None
    return total


def corrupt_chunk(path: Path, f: IO[bytes], number: int, chunks: int, ci: ChunkIndex,
                  exc: BaseException) -> CorruptChunk:
    return CorruptChunk(path, number, chunks, ci.chunk_start_offset,
                        indexed_message_count(f, ci), error_text(exc))


def indexed_messages(path: Path, f: IO[bytes], summary: Summary,
                     channel_ids: set[int] | None, lo: int, hi: int,
                     on_corrupt: Callable[[CorruptChunk], None]
                     ) -> Iterator[tuple[Channel, Message]]:
    """(channel, message) of a finished file in log-time order (ties: file order), messages
    with log times in [lo, hi) on channel_ids (None: all). A chunk that does not decode is
    given to on_corrupt and skipped; the others are read as needed (one chunk ahead of the
    messages it may interleave with, as mcap's own reader does)."""
    indexes = chunk_indexes(summary)
    # (time, 0 = a chunk to open / 1 = a message, chunk offset, position in chunk, payload)
    heap: list[tuple[int, int, int, int, Any]] = []
    for number, ci in enumerate(indexes, 1):
        if ci.message_end_time < lo or ci.message_start_time >= hi:
            continue
        if channel_ids is not None and ci.message_index_offsets and \
                not channel_ids.intersection(ci.message_index_offsets):
            continue
        heap.append((ci.message_start_time, 0, ci.chunk_start_offset, number, ci))
    heapq.heapify(heap)
    while heap:
        _time, kind, offset, position, item = heapq.heappop(heap)
        if kind == 1:
            yield summary.channels[item.channel_id], item
            continue
        try:
            records = decode_chunk(f, item, summary.channels)
        except CHUNK_ERRORS as exc:
            on_corrupt(corrupt_chunk(path, f, position, len(indexes), item, exc))
            continue
        for i, rec in enumerate(records):
            if isinstance(rec, Message) and lo <= rec.log_time < hi and \
                    (channel_ids is None or rec.channel_id in channel_ids):
                heapq.heappush(heap, (rec.log_time, 1, offset, i, rec))


@dataclass
class ChunkCheck:
    """What decoding every chunk of a finished file found."""

    chunks: int = 0
    messages: int = 0                            # messages in the good chunks
    counts: dict[int, int] | None = None         # per channel id, good chunks only
    start: int = 0
    end: int = 0
    corrupt: list[CorruptChunk] | None = None


def check_chunks(path: Path, f: IO[bytes], summary: Summary) -> ChunkCheck:
    """Decode every chunk the summary indexes and check its CRC."""
    indexes = chunk_indexes(summary)
    result = ChunkCheck(chunks=len(indexes), counts={}, corrupt=[], start=2**63 - 1)
    assert result.counts is not None and result.corrupt is not None
    for number, ci in enumerate(indexes, 1):
        try:
            records = decode_chunk(f, ci, summary.channels)
        except CHUNK_ERRORS as exc:
            result.corrupt.append(corrupt_chunk(path, f, number, len(indexes), ci, exc))
            continue
        for rec in records:
            if isinstance(rec, Message):
                result.messages += 1
                result.counts[rec.channel_id] = result.counts.get(rec.channel_id, 0) + 1
                result.start = min(result.start, rec.log_time)
                result.end = max(result.end, rec.log_time)
    return result
