"""bag_info: the summary `ros2 bag info` prints (rosbag2_py's format_bag_meta_data layout)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from .common import BagError, one_line
from .reader import BagReader, FileCheck, check_file, lost_messages

_INDENT = ' ' * 19  # width of 'Topic information: '


def format_size(size: int) -> str:
    """'1.2 MiB' as rosbag2 writes sizes (B without decimals, then one decimal)."""
    value, units = float(size), ['B', 'KiB', 'MiB', 'GiB', 'TiB']
    index = 0
    while value >= 1024 and index < len(units) - 1:
        value /= 1024
        index += 1
    return f'{value:.{0 if index == 0 else 1}f} {units[index]}'


def format_seconds(ns: int) -> str:
    return f'{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}'


def format_time(ns: int) -> str:
    """'Jun 12 2024 19:14:00.405568442 (1718212440.405568442)', local time."""
    try:
        date = time.strftime('%b %e %Y %H:%M:%S', time.localtime(ns // 1_000_000_000))
    except (OverflowError, OSError, ValueError):
        date = '?'
    return f'{date}.{ns % 1_000_000_000:09d} ({format_seconds(ns)})'


@dataclass
class BagCheck:
    """What `vizzy bag info --check` found: every chunk of every file decoded, CRCs checked."""

    storage: str
    files: list[FileCheck] = field(default_factory=list)
    error: str = ''  # sqlite3: the error that stopped reading ('' when none)
    messages_read: int = 0  # sqlite3

    @property
    def ok(self) -> bool:
        return not self.error and not any(f.corrupt or f.problem for f in self.files)

    def lines(self) -> list[str]:
        """'Check:' lines in bag_info's layout."""
        if self.storage != 'mcap':
            return ['Check:             ' + (f'FAILED after {self.messages_read} messages: '
                                             f'{self.error}' if self.error else
                                             f'OK: {self.messages_read} messages read')]
        chunks = sum(f.chunks for f in self.files)
        read = sum(f.messages for f in self.files)
        corrupt = [c for f in self.files for c in f.corrupt]
        if self.ok:
            return [f'Check:             OK: {chunks} chunks, {read} messages; every chunk '
                    'decompresses and matches its CRC']
        head = 'Check:             DAMAGED: '
        if corrupt:
            head += (f'{len(corrupt)} of {chunks} chunks corrupt, {lost_messages(corrupt)} '
                     f'unreadable, {read} readable; `vizzy bag reindex` drops the corrupt chunks')
        else:
            head += f'{chunks} chunks, {read} messages readable'
        lines = [head]
        lines += [_INDENT + c.describe() for c in corrupt]
        lines += [f'{_INDENT}{f.file.name}: {f.problem}' for f in self.files if f.problem]
        return lines


def bag_check(bag_dir: str | os.PathLike[str]) -> BagCheck:
    """Decode every chunk of every file of a bag and check its CRC (sqlite3: read every
    message). Never writes. Raises BagError when it is not a readable bag."""
    reader = BagReader(bag_dir, repair=False)
    result = BagCheck(reader.storage_identifier)
    if reader.storage_identifier == 'mcap':
        result.files = [check_file(Path(f)) for f in reader.files]
        return result
    try:
        for _ in reader.messages():
            result.messages_read += 1
    except BagError as exc:
        result.error = str(exc)
    except Exception as exc:  # noqa: BLE001 - rosbags / sqlite3 raise many types on bad data
        result.error = f'{type(exc).__name__}: {one_line(exc)}'
    return result


def bag_info(bag_dir: str | os.PathLike[str], *, check: bool = False) -> str:
    """The `ros2 bag info` text of a bag (files, size, storage, duration, start/end, messages,
    one line per topic with type, count and serialization format).

    Args:
        bag_dir: the bag directory. Never written: a killed recording is read as far as its
            complete chunks go and reported as unfinished (`vizzy bag reindex` repairs it).
        check: also decode every chunk and check its CRC (bag_check), ending with its 'Check:'
            lines. Without it only the summaries are read: a corrupt chunk goes unnoticed.

    Raises BagError when it is not a readable bag.
    """
    reader = BagReader(bag_dir, repair=False)
    meta = reader.metadata
    files = [f.name for f in reader.files]
    start = reader.start_time_ns if reader.message_count else 0
    lines = [
        'Files:             ' + f'\n{_INDENT}'.join(files),
        'Bag size:          ' + format_size(reader.size_bytes),
        'Storage id:        ' + reader.storage_identifier,
        'ROS Distro:        ' + (meta.ros_distro or 'unknown'),
        'Duration:          ' + format_seconds(reader.duration_ns) + 's',
        'Start:             ' + format_time(start),
        'End:               ' + format_time(start + reader.duration_ns),
        'Messages:          ' + str(reader.message_count),
    ]
    topics = sorted(meta.topics, key=lambda t: t.name)
    topic_lines = [f'Topic: {t.name} | Type: {t.type} | Count: {t.message_count} | '
                   f'Serialization Format: {t.serialization_format}' for t in topics]
    lines.append('Topic information: ' + f'\n{_INDENT}'.join(topic_lines))
    lines += ['Service:           0', 'Service information: ']
    if reader.unfinished_files:
        lines.append('Unfinished:        ' + ', '.join(f.name for f in reader.unfinished_files)
                     + ' (a killed recording, counted up to its last complete chunk; '
                     '`vizzy bag reindex` repairs it)')
    if check:
        lines += bag_check(bag_dir).lines()
    return '\n'.join(lines) + '\n'
