"""What rosbag2 (Jazzy) writes besides the messages: metadata.yaml (version 9) and QoS profiles.

Formats follow rosbag2_storage's yaml.hpp / qos.cpp (Jazzy):
- metadata.yaml: `rosbag2_bagfile_information` with the fields in yaml-cpp's emission order;
  offered_qos_profiles is a YAML list since version 9 (a YAML string in version 4..8);
- MCAP channel metadata `offered_qos_profiles`: the same list dumped to a YAML string;
- QoS enums as rmw's lower-case names (version 9) or their integers (older bags, read only);
- infinite durations as {sec: 9223372036, nsec: 854775807} (RMW_DURATION_INFINITE).
"""

from __future__ import annotations

import contextlib
import os
import select
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import yaml

METADATA_FILE = 'metadata.yaml'
METADATA_VERSION = 9
ROS_DISTRO = 'jazzy'
INFINITE_NS = 2**63 - 1  # RMW_DURATION_INFINITE in nanoseconds
MCAP_MAGIC = b'\x89MCAP0\r\n'

# rmw enum values (older metadata stores integers) and their rmw_*_to_str names (version 9).
_HISTORY = {0: 'system_default', 1: 'keep_last', 2: 'keep_all', 3: 'unknown'}
_RELIABILITY = {0: 'system_default', 1: 'reliable', 2: 'best_effort', 3: 'unknown',
                4: 'best_available'}
_DURABILITY = {0: 'system_default', 1: 'transient_local', 2: 'volatile', 3: 'unknown',
               4: 'best_available'}
_LIVELINESS = {0: 'system_default', 1: 'automatic', 2: 'manual_by_node', 3: 'manual_by_topic',
               4: 'unknown', 5: 'best_available'}
# "Infinite" as RMW implementations reported it before RMW_DURATION_INFINITE (Foxy bags).
_LEGACY_INFINITE = {(0x7FFFFFFF, 0xFFFFFFFF), (0x7FFFFFFF, 0x7FFFFFFF), (9223372036, 854775807)}


class BagError(Exception):
    """A bag cannot be read or written; the message names the path and the problem."""


class StopRequest:
    """A stop flag that a signal handler may set wherever the main thread is, with a wait()
    that ends as soon as it is set (from the handler, or from any thread).

    threading.Event will not do: its set() takes the Event's lock, which the main thread holds
    around the bookkeeping of Event.wait(); a SIGINT handler calling set() at that moment waits
    for ever for its own thread, and so does every later Ctrl-C (a recording that would not
    stop). Here set() assigns a flag and writes a byte to a pipe that wait() selects on: no
    lock, nothing that can block.
    """

    def __init__(self) -> None:
        self._set = False
        self._read_fd, self._write_fd = os.pipe()
        os.set_blocking(self._write_fd, False)

    def set(self) -> None:
        self._set = True  # before the byte: whoever wakes up sees the flag
        with contextlib.suppress(OSError):  # pipe full: a wake-up is pending anyway
            os.write(self._write_fd, b'\0')

    def is_set(self) -> bool:
        return self._set

    def wait(self, timeout: float | None = None) -> bool:
        """Until set() or `timeout` seconds (None: no limit); True if set."""
        if not self._set and (timeout is None or timeout > 0):
            # a signal handled during select() that calls set() makes the retried select return
            select.select([self._read_fd], [], [], timeout)
        return self._set

    def __del__(self) -> None:
        # only when nothing can call set() any more: the descriptors cannot be reused under it
        for fd in (getattr(self, '_read_fd', -1), getattr(self, '_write_fd', -1)):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)


def one_line(exc: BaseException) -> str:
    """An exception's text on one line (YAML errors, for one, span several)."""
    return ' '.join(str(exc).split()) or type(exc).__name__


@dataclass(frozen=True)
class QosProfile:
    """One offered QoS profile as rosbag2 stores it (rclcpp::QoS fields)."""

    history: str = 'keep_last'
    depth: int = 10
    reliability: str = 'reliable'
    durability: str = 'volatile'
    deadline_ns: int = INFINITE_NS
    lifespan_ns: int = INFINITE_NS
    liveliness: str = 'automatic'
    liveliness_lease_duration_ns: int = INFINITE_NS
    avoid_ros_namespace_conventions: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The version 9 YAML mapping, keys in rosbag2's order."""
        return {
            'history': self.history,
            'depth': self.depth,
            'reliability': self.reliability,
            'durability': self.durability,
            'deadline': _time_to_dict(self.deadline_ns),
            'lifespan': _time_to_dict(self.lifespan_ns),
            'liveliness': self.liveliness,
            'liveliness_lease_duration': _time_to_dict(self.liveliness_lease_duration_ns),
            'avoid_ros_namespace_conventions': self.avoid_ros_namespace_conventions,
        }

    @classmethod
    def from_dict(cls, item: dict[str, Any]) -> QosProfile:
        """Parse a version 9 (names) or version 4..8 (integers) mapping."""
        try:
            return cls(
                history=_enum(item['history'], _HISTORY),
                depth=int(item['depth']),
                reliability=_enum(item['reliability'], _RELIABILITY),
                durability=_enum(item['durability'], _DURABILITY),
                deadline_ns=_time_from_dict(item['deadline']),
                lifespan_ns=_time_from_dict(item['lifespan']),
                liveliness=_enum(item['liveliness'], _LIVELINESS),
                liveliness_lease_duration_ns=_time_from_dict(item['liveliness_lease_duration']),
                avoid_ros_namespace_conventions=bool(item.get('avoid_ros_namespace_conventions',
                                                              False)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f'bad QoS profile {item!r}: {exc}') from None

    @classmethod
    def from_dds(cls, qos: Any) -> QosProfile:
        """From a discovered endpoint's vizzy_runtime.dds.QoS."""
        return cls(
            history='keep_all' if qos.keep_all else 'keep_last',
            depth=0 if qos.keep_all else qos.depth,
            reliability='reliable' if qos.reliable else 'best_effort',
            durability='transient_local' if qos.transient_local else 'volatile',
            deadline_ns=qos.deadline_ns or INFINITE_NS,
            lifespan_ns=qos.lifespan_ns or INFINITE_NS,
            liveliness='manual_by_topic' if qos.liveliness_manual else 'automatic',
            liveliness_lease_duration_ns=qos.liveliness_lease_ns or INFINITE_NS,
        )

    def to_dds(self) -> Any:
        """The vizzy_runtime.dds.QoS offering this profile ('unknown' policies -> ROS defaults)."""
        from .. import dds

        def finite(ns: int) -> int | None:
            return ns if 0 < ns < INFINITE_NS else None

        return dds.QoS(
            reliable=self.reliability != 'best_effort',
            transient_local=self.durability == 'transient_local',
            keep_all=self.history == 'keep_all',
            depth=self.depth if self.depth > 0 else 10,
            deadline_ns=finite(self.deadline_ns),
            lifespan_ns=finite(self.lifespan_ns),
            liveliness_manual=self.liveliness == 'manual_by_topic',
            liveliness_lease_ns=finite(self.liveliness_lease_duration_ns),
        )


def _enum(value: Any, names: dict[int, str]) -> str:
    if isinstance(value, bool):
        raise ValueError(f'bad policy value {value!r}')
    if isinstance(value, int):
        return names.get(value, 'unknown')
    value = str(value).lower()
    if value not in names.values():
        raise ValueError(f'unknown policy value {value!r}')
    return value


def _time_to_dict(ns: int) -> dict[str, int]:
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def _time_from_dict(item: dict[str, Any]) -> int:
    sec, nsec = int(item['sec']), int(item['nsec'])
    if (sec, nsec) in _LEGACY_INFINITE:
        return INFINITE_NS
    return min(sec * 1_000_000_000 + nsec, INFINITE_NS)


def parse_qos_profiles(value: Any) -> list[QosProfile]:
    """offered_qos_profiles from metadata (list, v9) or a YAML string (channel metadata, v4..8)."""
    if isinstance(value, str):
        value = yaml.safe_load(value) if value.strip() else []
    if not value:
        return []
    if not isinstance(value, list):
        raise ValueError(f'offered_qos_profiles is not a list: {value!r}')
    return [QosProfile.from_dict(item) for item in value]


def dump_qos_profiles(profiles: list[QosProfile] | tuple[QosProfile, ...]) -> str:
    """The YAML string rosbag2 puts in MCAP channel metadata (serialize_rclcpp_qos_vector, v9)."""
    return dump_yaml([p.to_dict() for p in profiles]).rstrip('\n')


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag, as metadata.yaml lists it."""

    name: str
    type: str
    serialization_format: str = 'cdr'
    offered_qos_profiles: tuple[QosProfile, ...] = ()
    type_description_hash: str = ''
    message_count: int = 0


@dataclass(frozen=True)
class FileInfo:
    """One storage file of a bag (metadata.yaml `files`)."""

    path: str
    starting_time_ns: int
    duration_ns: int
    message_count: int


class BagMessage(NamedTuple):
    """A message as stored: CDR bytes verbatim, receive (log) and send (publish) times in ns."""

    topic: str
    typename: str
    data: bytes
    log_time_ns: int
    publish_time_ns: int


@dataclass
class BagMetadata:
    """The content of metadata.yaml (rosbag2_bagfile_information)."""

    storage_identifier: str
    files: list[FileInfo]
    topics: list[TopicInfo]
    version: int = METADATA_VERSION
    compression_format: str = ''
    compression_mode: str = ''
    custom_data: dict[str, str] = field(default_factory=dict)
    ros_distro: str = ROS_DISTRO
    relative_file_paths: list[str] | None = None

    @property
    def message_count(self) -> int:
        return sum(f.message_count for f in self.files)

    @property
    def starting_time_ns(self) -> int:
        starts = [f.starting_time_ns for f in self.files if f.message_count]
        return min(starts) if starts else INFINITE_NS

    @property
    def duration_ns(self) -> int:
        ends = [f.starting_time_ns + f.duration_ns for f in self.files if f.message_count]
        return max(ends) - self.starting_time_ns if ends else 0

    def to_dict(self) -> dict[str, Any]:
        """The inner mapping, keys in rosbag2's (yaml-cpp's) order."""
        return {
            'version': self.version,
            'storage_identifier': self.storage_identifier,
            'duration': {'nanoseconds': self.duration_ns},
            'starting_time': {'nanoseconds_since_epoch': self.starting_time_ns},
            'message_count': self.message_count,
            'topics_with_message_count': [
                {'topic_metadata': {
                    'name': t.name,
                    'type': t.type,
                    'serialization_format': t.serialization_format,
                    'offered_qos_profiles': [p.to_dict() for p in t.offered_qos_profiles],
                    'type_description_hash': t.type_description_hash,
                }, 'message_count': t.message_count}
                for t in self.topics
            ],
            'compression_format': self.compression_format,
            'compression_mode': self.compression_mode,
            'relative_file_paths': (self.relative_file_paths if self.relative_file_paths
                                    is not None else [f.path for f in self.files]),
            'files': [
                {'path': f.path,
                 'starting_time': {'nanoseconds_since_epoch': f.starting_time_ns},
                 'duration': {'nanoseconds': f.duration_ns},
                 'message_count': f.message_count}
                for f in self.files
            ],
            'custom_data': dict(self.custom_data) or None,
            'ros_distro': self.ros_distro,
        }

    def dump(self) -> str:
        """metadata.yaml text."""
        return dump_yaml({'rosbag2_bagfile_information': self.to_dict()})

    def write(self, bag_dir: Path) -> None:
        """Write metadata.yaml atomically (a reader never sees half a file)."""
        path = Path(bag_dir) / METADATA_FILE
        tmp = path.with_name(METADATA_FILE + '.tmp')
        with open(tmp, 'w', encoding='utf-8') as out:
            out.write(self.dump())
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path) -> BagMetadata:
        """Parse a metadata.yaml (versions 4..9); BagError naming the file on any problem."""
        try:
            doc = yaml.safe_load(Path(path).read_text(encoding='utf-8'))
            info = doc['rosbag2_bagfile_information']
            version = int(info['version'])
            topics = []
            for item in info.get('topics_with_message_count') or []:
                meta = item['topic_metadata']
                topics.append(TopicInfo(
                    name=meta['name'], type=meta['type'],
                    serialization_format=meta.get('serialization_format', 'cdr'),
                    offered_qos_profiles=tuple(
                        parse_qos_profiles(meta.get('offered_qos_profiles'))),
                    type_description_hash=meta.get('type_description_hash') or '',
                    message_count=int(item.get('message_count', 0))))
            paths = [str(p) for p in info.get('relative_file_paths') or []]
            files = [FileInfo(f['path'], int(f['starting_time']['nanoseconds_since_epoch']),
                              int(f['duration']['nanoseconds']), int(f['message_count']))
                     for f in info.get('files') or []]
            if not files:  # version < 5 has no per-file entries; one entry for the whole bag
                files = [FileInfo(p, int(info['starting_time']['nanoseconds_since_epoch']),
                                  int(info['duration']['nanoseconds']),
                                  int(info['message_count']) if i == 0 else 0)
                         for i, p in enumerate(paths)]
            return cls(storage_identifier=str(info['storage_identifier']), files=files,
                       topics=topics, version=version,
                       compression_format=info.get('compression_format') or '',
                       compression_mode=info.get('compression_mode') or '',
                       custom_data={str(k): str(v)
                                    for k, v in (info.get('custom_data') or {}).items()},
                       ros_distro=info.get('ros_distro') or '', relative_file_paths=paths)
        except OSError as exc:
            raise BagError(f'{path}: cannot read: {exc.strerror}') from None
        except (yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError) as exc:
            raise BagError(f'{path}: not a valid rosbag2 metadata file ({type(exc).__name__}: '
                           f'{one_line(exc)})') from None


class _Dumper(yaml.SafeDumper):
    """PyYAML emitting the way yaml-cpp does for rosbag2: indented block sequences, `""`, `~`."""

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        return super().increase_indent(flow, False)


def _represent_str(dumper: yaml.SafeDumper, value: str) -> yaml.Node:
    if value == '':
        return dumper.represent_scalar('tag:yaml.org,2002:str', '', style='"')
    return dumper.represent_str(value)


_Dumper.add_representer(str, _represent_str)
_Dumper.add_representer(type(None),
                        lambda d, _v: d.represent_scalar('tag:yaml.org,2002:null', '~'))


def dump_yaml(data: Any) -> str:
    """YAML text the way rosbag2 (yaml-cpp) emits it."""
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, default_flow_style=False,
                     allow_unicode=True, width=1 << 16)


def mcap_has_footer(path: Path) -> bool:
    """True if the file ends with an MCAP footer record and magic (the writer was closed)."""
    try:
        with open(path, 'rb') as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            if size < 8 + 9 + 20 + 8 + 8:
                return False
            f.seek(size - 37)
            tail = f.read(37)
    except OSError:
        return False
    return tail[-8:] == MCAP_MAGIC and tail[0] == 0x02 and tail[1:9] == (20).to_bytes(8, 'little')
