"""bag_info: the summary `ros2 bag info` prints (rosbag2_py's format_bag_meta_data layout)."""

from __future__ import annotations

import os
import time

from .reader import BagReader

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


def bag_info(bag_dir: str | os.PathLike[str]) -> str:
    """The `ros2 bag info` text of a bag (files, size, storage, duration, start/end, messages,
    one line per topic with type, count and serialization format).

    Args:
        bag_dir: the bag directory. Never written: a killed recording is read as far as its
            complete chunks go and reported as unfinished (`vizzy bag reindex` repairs it).

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
    return '\n'.join(lines) + '\n'
