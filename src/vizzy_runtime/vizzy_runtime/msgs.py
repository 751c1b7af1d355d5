"""Message types for the bundled runtime: rosbags' Jazzy typestore plus our msgs/msg/*.msg.

Nothing here is copied by hand from a .msg file: standard types come from rosbags'
ROS 2 Jazzy store, ours are parsed at import time from the interface package. Jazzy packages the
store lacks (BUNDLED_PACKAGES: vision_msgs 4.1.1) are parsed from .msg files shipped as this
package's data (interfaces/<pkg>/msg/*.msg, the released package's fields, so the RIHS01 hashes
are the released ones: test_vision_msgs.py); they are no colcon package, so they never shadow apt
ROS 2's own vision_msgs.

Each type gets an rclpy-like class (default-constructible, keyword arguments, primitive
sequences as numpy arrays) that rosbags' generated CDR code both fills on deserialization
and reads on serialization, so a message crosses the wire without per-element Python work.
"""

from __future__ import annotations

import keyword
import os
import threading
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

OUR_PACKAGE = 'active_vision_msgs'
# ROS 2 Jazzy interface packages that rosbags' Jazzy store lacks, shipped as package data.
BUNDLED_PACKAGES = ('vision_msgs',)

# 'byte' is int8 as in rosbags' generated code, so built and received messages compare equal.
_NUMPY = {
    'bool': np.bool_, 'byte': np.int8, 'char': np.uint8, 'int8': np.int8, 'uint8': np.uint8,
    'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32, 'uint32': np.uint32,
    'int64': np.int64, 'uint64': np.uint64, 'float32': np.float32, 'float64': np.float64,
}


def msgs_dir() -> Path:
    """Where active_vision_msgs' .msg files are: $VIZZY_MSGS_DIR, else the repository's msgs/msg."""
    env = os.environ.get('VIZZY_MSGS_DIR')
    if env:
        return Path(env)
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / 'msgs' / 'msg'
        if cand.is_dir():
            return cand
    raise FileNotFoundError(
        'active_vision_msgs definitions not found: set VIZZY_MSGS_DIR to the msgs/msg folder')


def bundled_msg_texts(package: str) -> dict[str, str]:
    """Type name (vision_msgs/msg/Detection2D) -> .msg text, for a package of BUNDLED_PACKAGES
    (vizzy_runtime's package data interfaces/<package>/msg/*.msg)."""
    if package not in BUNDLED_PACKAGES:
        raise ValueError(f'no bundled interface package {package!r} (have '
                         f'{", ".join(BUNDLED_PACKAGES)})')
    folder = resources.files('vizzy_runtime') / 'interfaces' / package / 'msg'
    texts = {f'{package}/msg/{entry.name[:-4]}': entry.read_text(encoding='utf-8')
             for entry in folder.iterdir() if entry.name.endswith('.msg')}
    if not texts:
        raise FileNotFoundError(f'{package}: no .msg files in {folder} (vizzy_runtime installed '
                                'without its package data?)')
    return dict(sorted(texts.items()))


def normalize_type_name(name: str) -> str:
    """'sensor_msgs/Image' or 'sensor_msgs/msg/Image' or 'sensor_msgs.msg.Image' ->
    'sensor_msgs/msg/Image'."""
    parts = name.replace('.', '/').split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or not all(parts):
        raise ValueError(f'not a message type name: {name!r} (expected pkg/msg/Type)')
    return '/'.join(parts)


def dds_type_name(typename: str) -> str:
    """ROS 2 DDS type name, e.g. sensor_msgs/msg/Image -> sensor_msgs::msg::dds_::Image_."""
    pkg, kind, name = normalize_type_name(typename).split('/')
    return f'{pkg}::{kind}::dds_::{name}_'


def ros_type_from_dds(dds_name: str) -> str | None:
    """Inverse of dds_type_name; None for names that are not ROS 2 message types."""
    parts = dds_name.split('::')
    if len(parts) != 4 or parts[2] != 'dds_' or not parts[3].endswith('_'):
        return None
    return f'{parts[0]}/{parts[1]}/{parts[3][:-1]}'


class _Registry:
    """The typestore and the rclpy-like message classes built from it (lazily, thread-safe)."""

    def __init__(self) -> None:
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self._lock = threading.RLock()
        self._classes: dict[str, type] = {}
        self.ours: list[str] = []
        self._load_ours()
        self.bundled: list[str] = []    # the types of BUNDLED_PACKAGES
        self._load_bundled()

    def _load_ours(self) -> None:
        try:
            folder = msgs_dir()
        except FileNotFoundError:
            return
        texts = {}
        for path in sorted(folder.glob('*.msg')):
            texts.update(get_types_from_msg(path.read_text(), f'{OUR_PACKAGE}/msg/{path.stem}'))
        self.store.register(texts)
        self.ours = sorted(texts)

    def _load_bundled(self) -> None:
        texts = {}
        for package in BUNDLED_PACKAGES:
            for name, text in bundled_msg_texts(package).items():
                texts.update(get_types_from_msg(text, name))
        self.store.register(texts)
        self.bundled = sorted(texts)

    def fields(self, typename: str) -> list[tuple[str, Any]]:
        return self.store.fielddefs[typename][1]

    def constants(self, typename: str) -> Sequence[tuple[str, str, Any]]:
        return self.store.fielddefs[typename][0]

    def get_class(self, typename: str) -> type:
        typename = normalize_type_name(typename)
        with self._lock:
            cls = self._classes.get(typename)
            if cls is None:
                if typename not in self.store.fielddefs:
                    raise KeyError(f'unknown message type {typename!r}')
                cls = _make_class(self, typename)
                self._classes[typename] = cls
                # rosbags' generated deserializer instantiates store.types[...] positionally.
                self.store.types[typename] = cls
                self.store.cache.pop(typename, None)
                for nested in _nested_names(self.fields(typename)):
                    self.get_class(nested)
            return cls


def _nested_names(fields: list[tuple[str, Any]]) -> list[str]:
    out = []
    for _, desc in fields:
        while desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            desc = desc[1][0]
        if desc[0] == Nodetype.NAME:
            out.append(desc[1])
    return out


# Default values declared in upstream .msg files (rosbags' store keeps no defaults).
_FIELD_DEFAULTS: dict[tuple[str, str], Any] = {('geometry_msgs/msg/Quaternion', 'w'): 1.0}


def _primitive_array(desc: Any) -> tuple[Any, int | None] | None:
    """(dtype, fixed length or None) for a field that is a sequence/array of numbers, else None."""
    kind, rest = desc
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        sub, length = rest
        if sub[0] == Nodetype.BASE and sub[1][0] in _NUMPY:
            return _NUMPY[sub[1][0]], (length if kind == Nodetype.ARRAY else None)
    return None


def _array_property(typename: str, name: str, dtype: Any, length: int | None) -> property:
    """Like rclpy's setters: lists, bytes and array.array become a numpy array (no copy when already
    one of the right dtype); a fixed-size array of the wrong length is refused."""
    slot = '_' + name

    def fget(self: Any) -> Any:
        return getattr(self, slot)

    def fset(self: Any, value: Any) -> None:
        if not (isinstance(value, np.ndarray) and value.dtype == dtype and value.ndim == 1):
            if isinstance(value, (bytes, bytearray, memoryview)) or type(value).__name__ == 'array':
                value = np.frombuffer(value,
                                      dtype=np.uint8).view(dtype) if np.dtype(dtype).itemsize == 1 \
                    else np.asarray(value, dtype=dtype)
            else:
                value = np.asarray(value, dtype=dtype).reshape(-1)
        if length is not None and value.size != length:
            raise ValueError(f'{typename}.{name} must have exactly {length} elements, got '
                             f'{value.size}')
        setattr(self, slot, value)

    return property(fget, fset)


def _default_factory(registry: _Registry, desc: Any) -> Any:
    """A zero-argument callable giving the rclpy default value for one field."""
    kind, rest = desc
    if kind == Nodetype.BASE:
        name = rest[0]
        if name in ('string', 'bounded_string'):
            return str
        if name == 'bool':
            return bool
        if name in ('float32', 'float64'):
            return float
        return int
    if kind == Nodetype.NAME:
        return lambda: registry.get_class(rest)()
    sub, length = rest
    if sub[0] == Nodetype.BASE and sub[1][0] in _NUMPY:
        dtype = _NUMPY[sub[1][0]]
        size = length if kind == Nodetype.ARRAY else 0
        return lambda: np.zeros(size, dtype=dtype)
    if kind == Nodetype.ARRAY:
        item = _default_factory(registry, sub)
        return lambda: [item() for _ in range(length)]
    return list


def _generic_init(typename: str, names: list[str], factories: dict[str, Any]) -> Any:
    """__init__(*fields, **fields) for any field names: a field not given, or given as None,
    gets its default."""
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        if len(args) > len(names):
            raise TypeError(f'{typename} takes at most {len(names)} positional arguments')
        for name, value in zip(names, args, strict=False):
            setattr(self, name, factories[name]() if value is None else value)
        for name in names[len(args):]:
            value = kwargs.pop(name, None)
            setattr(self, name, factories[name]() if value is None else value)
        if kwargs:
            raise TypeError(f'{typename} has no field(s) {sorted(kwargs)}')
    return __init__


def _make_init(typename: str, names: list[str], factories: dict[str, Any]) -> Any:
    """The class's __init__, generated with one parameter per field: rosbags' deserializer
    builds every (nested) message through it (a TFMessage of 5 transforms: 31 objects), and a
    generic loop over names, setattr and kwargs cost 3 to 4 times as much (issue 27). Same
    behaviour as _generic_init, which field names that are no Python identifiers still use."""
    if not all(n.isidentifier() and not keyword.iskeyword(n) and not n.startswith('_')
               and n != 'self'
               for n in names) or len(names) > 200:
        return _generic_init(typename, names, factories)
    params = ''.join(f', {n}=None' for n in names)
    body = ''.join(f'    self.{n} = _f_{n}() if {n} is None else {n}\n' for n in names)
    source = (f'def __init__(self{params}, *_args, **_kwargs):\n'
              '    if _args or _kwargs:\n'
              '        _refuse(len(_args), _kwargs)\n'
              f'{body}')

    def refuse(extra: int, kwargs: dict[str, Any]) -> None:
        if extra:
            raise TypeError(f'{typename} takes at most {len(names)} positional arguments')
        raise TypeError(f'{typename} has no field(s) {sorted(kwargs)}')

    scope: dict[str, Any] = {f'_f_{n}': factories[n] for n in names}
    scope['_refuse'] = refuse
    exec(compile(source, f'<{typename}.__init__>', 'exec'), scope)  # noqa: S102 - our source
    return scope['__init__']


def _make_class(registry: _Registry, typename: str) -> type:
    fields = registry.fields(typename)
    names = [name for name, _ in fields]
    factories = {name: _default_factory(registry, desc) for name, desc in fields}
    for (owner, name), value in _FIELD_DEFAULTS.items():
        if owner == typename:
            factories[name] = lambda value=value: value
    arrays = {name: spec for name, desc in fields if (spec := _primitive_array(desc))}
    sequences = {name for name, (_dtype, length) in arrays.items() if length is None}
    pkg, kind, short = typename.split('/')

    __init__ = _make_init(typename, names, factories)

    def __eq__(self: Any, other: object) -> bool:
        if getattr(other, '__msgtype__', None) != typename:
            return NotImplemented
        for name in names:
            a, b = getattr(self, name), getattr(other, name)
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
                if not np.array_equal(np.asarray(a), np.asarray(b)):
                    return False
            elif a != b:
                return False
        return True

    def __repr__(self: Any) -> str:
        # as rclpy's generated __repr__: a sequence of numbers prints as a list (rclpy keeps it
        # in an array.array and strips the 'array(...)'), a fixed-size array as numpy's repr
        inner = ', '.join(
            f'{n}={getattr(self, n).tolist()!r}' if n in sequences else f'{n}={getattr(self, n)!r}'
            for n in names)
        return f'{pkg}.{kind}.{short}({inner})'

    namespace: dict[str, Any] = {
        '__slots__': tuple('_' + n if n in arrays else n for n in names),
        '__init__': __init__,
        '__eq__': __eq__,
        '__hash__': None,
        '__repr__': __repr__,
        '__msgtype__': typename,
        '__module__': f'{pkg}.msg',
        '_fields_and_field_types': {name: str(desc) for name, desc in fields},
        'get_fields_and_field_types': classmethod(lambda cls: dict(cls._fields_and_field_types)),
    }
    for cname, _ctype, cvalue in registry.constants(typename):
        namespace[cname] = cvalue
    for name, (dtype, length) in arrays.items():
        namespace[name] = _array_property(typename, name, dtype, length)
    return type(short, (), namespace)


_registry: _Registry | None = None
_registry_lock = threading.Lock()


def registry() -> _Registry:
    global _registry
    if _registry is not None:       # made once; no lock on the per-message path
        return _registry
    with _registry_lock:
        if _registry is None:
            _registry = _Registry()
        return _registry


def loaded_types() -> list[str]:
    """The message types whose classes exist so far (get_message and what they nest)."""
    reg = registry()
    with reg._lock:
        return list(reg._classes)


def get_message(typename: str) -> type:
    """The bundled runtime's class for a message type ('sensor_msgs/msg/Image')."""
    return registry().get_class(typename)


def type_of(msg_or_cls: Any) -> str:
    """'pkg/msg/Type' of a message instance or class (bundled or real rclpy)."""
    name = getattr(msg_or_cls, '__msgtype__', None)
    if name:
        return name
    cls = msg_or_cls if isinstance(msg_or_cls, type) else type(msg_or_cls)
    module = cls.__module__.split('.')
    return f'{module[0]}/msg/{cls.__name__}'


# Type names (as given) whose classes exist: every message sent or received passes here, and
# the registry's lock and the name's normalization cost more than a small message's CDR.
_prepared: set[str] = set()


def _store_for(typename: str) -> Any:
    reg = registry()
    if typename not in _prepared:
        reg.get_class(typename)
        _prepared.add(typename)
    return reg.store


def serialize(msg: Any, typename: str | None = None) -> memoryview:
    """XCDR1 little-endian bytes with the 4-byte encapsulation header, as ROS 2 sends them."""
    typename = typename or type_of(msg)
    return _store_for(typename).serialize_cdr(msg, typename)


def deserialize(raw: bytes | memoryview, typename: str) -> Any:
    """Message object from CDR bytes; primitive arrays are numpy views over `raw` (no copy)."""
    # a memoryview, so rosbags' rawdata[4:] does not copy the payload
    return _store_for(typename).deserialize_cdr(
        raw if isinstance(raw, memoryview) else memoryview(raw), typename)


def message_definition(typename: str) -> str:
    """The concatenated .msg text rosbag2 stores as an MCAP schema (ros2msg encoding)."""
    return registry().store.generate_msgdef(normalize_type_name(typename), ros_version=2)[0]
