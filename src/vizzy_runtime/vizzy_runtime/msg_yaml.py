"""Messages to YAML and back, as ROS 2's command line tools do it (rosidl_runtime_py, Jazzy).

- to_yaml(): `ros2 topic echo`'s text (rosidl_runtime_py.message_to_yaml): PyYAML block style,
  fields in definition order, sequences as YAML lists, `false`/`true`, strings and sequences cut
  after truncate_length (a last item '...'), primitive arrays as plain lists;
- set_fields(): fill a message from the YAML mapping a user typed (`ros2 topic pub`,
  `ros2 service call`: rosidl_runtime_py.set_message_fields), with 'auto' for a std_msgs/Header
  and 'now' for a builtin_interfaces/Time (stamped at each publish), and one-line errors naming
  the field.

Both work on the bundled runtime's message classes (vizzy_runtime.msgs), whose field
definitions come from the typestore.
"""

from __future__ import annotations

import sys
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import yaml
from rosbags.interfaces import Nodetype

from . import msgs

DEFAULT_TRUNCATE_LENGTH = 128   # ros2 topic echo's default
EMPTY_FIELD = 'structure_needs_at_least_one_member'   # the IDL filler of an empty message

# rosidl_parser's names of the primitive types (what `--no-arr` prints)
_IDL_NAMES = {'float32': 'float', 'float64': 'double', 'bool': 'boolean', 'byte': 'octet',
              'char': 'uint8'}
_INT_RANGES = {f'{s}int{b}': ((0, 2**b - 1) if s else (-(2**(b - 1)), 2**(b - 1) - 1))
               for s in ('', 'u') for b in (8, 16, 32, 64)}
_INT_RANGES.update({'byte': (0, 255), 'char': (0, 255)})


class _Dumper(yaml.Dumper):
    """yaml.Dumper writing an OrderedDict as a plain mapping in its order (rosidl_runtime_py
    registers the same representer globally; here it is kept to our own dumper)."""


def _represent_ordereddict(dumper: yaml.Dumper, data: OrderedDict[Any, Any]) -> yaml.Node:
    return yaml.nodes.MappingNode('tag:yaml.org,2002:map',
                                  [(dumper.represent_data(k), dumper.represent_data(v))
                                   for k, v in data.items()])


_Dumper.add_representer(OrderedDict, _represent_ordereddict)


def fields_of(typename: str) -> list[tuple[str, Any]]:
    """(name, rosbags field description) of a message type, the IDL filler left out."""
    return [(n, d) for n, d in msgs.registry().fields(typename) if n != EMPTY_FIELD]


def _type_name(desc: Any) -> str:
    kind, rest = desc
    if kind == Nodetype.NAME:
        return str(rest)
    name = rest[0]
    return 'string' if name in ('string', 'bounded_string') else _IDL_NAMES.get(name, name)


def _abbreviate(desc: Any, value: Any) -> str:
    """`--no-arr`'s text for an array field (rosidl_runtime_py __abbreviate_array_info)."""
    kind, (sub, length) = desc
    item = _type_name(sub)
    if kind == Nodetype.ARRAY:
        return f'<array type: {item}[{length}]>'
    if length:
        return f'<sequence type: {item}[{length}], length: {len(value)}>'
    return f'<sequence type: {item}, length: {len(value)}>'


def _plain(value: Any, desc: Any, truncate: int | None, no_arr: bool, no_str: bool) -> Any:
    """One field's value as rosidl_runtime_py's _convert_value gives it."""
    kind, rest = desc
    if kind == Nodetype.NAME:
        return to_ordereddict(value, truncate_length=truncate, no_arr=no_arr, no_str=no_str)
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        if no_arr:
            return _abbreviate(desc, value)
        sub = rest[0]
        items = value.tolist() if hasattr(value, 'tolist') else list(value)
        cut = truncate is not None and len(items) > truncate
        out = [_plain(v, sub, truncate, no_arr, no_str) for v in (items[:truncate] if cut
                                                                   else items)]
        return out + ['...'] if cut else out
    name = rest[0]
    if hasattr(value, 'item'):        # a numpy scalar
        value = value.item()
    if name == 'byte' and isinstance(value, int):
        return chr(value & 0xFF)      # rclpy's byte is a bytes object, echoed as its character
    if isinstance(value, str):
        if no_str:
            return f'<string length: <{len(value)}>>'
        if truncate is not None and len(value) > truncate:
            return value[:truncate] + '...'
    return value


def to_ordereddict(msg: Any, *, truncate_length: int | None = None, no_arr: bool = False,
                   no_str: bool = False) -> OrderedDict[str, Any]:
    """rosidl_runtime_py.message_to_ordereddict for a bundled-runtime message."""
    out: OrderedDict[str, Any] = OrderedDict()
    for name, desc in fields_of(msgs.type_of(msg)):
        out[name] = _plain(getattr(msg, name), desc, truncate_length, no_arr, no_str)
    return out


def to_yaml(msg: Any, *, truncate_length: int | None = DEFAULT_TRUNCATE_LENGTH,
            no_arr: bool = False, no_str: bool = False, flow_style: bool = False) -> str:
    """`ros2 topic echo`'s YAML of one message (ends with a newline; echo then prints '---')."""
    return yaml.dump(to_ordereddict(msg, truncate_length=truncate_length, no_arr=no_arr,
                                    no_str=no_str),
                     Dumper=_Dumper, allow_unicode=True, width=sys.maxsize,
                     default_flow_style=flow_style)


# --- YAML -> message ---------------------------------------------------------------------------

class FieldError(ValueError):
    """A value that cannot go into a message field; the text names the field path."""


StampSetter = Callable[[Any], None]


def parse_values(text: str) -> dict[str, Any]:
    """The YAML mapping of `ros2 topic pub` / `ros2 service call` ('' or '{}': no fields)."""
    try:
        values = yaml.safe_load(text) if text.strip() else {}
    except yaml.YAMLError as err:
        raise FieldError(f'not YAML ({" ".join(str(err).split())})') from None
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise FieldError('The passed value needs to be a dictionary in YAML format')
    return values


def _int(value: Any, base: str, path: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
        raise FieldError(f'{path}: expected an integer ({base}), got {value!r}')
    lo, hi = _INT_RANGES[base]
    if not lo <= int(value) <= hi:
        raise FieldError(f'{path}: {value} is out of the range of {base} [{lo}, {hi}]')
    return int(value)


def _base(value: Any, base: str, bound: int, path: str) -> Any:
    if base in ('string', 'bounded_string'):
        if isinstance(value, (dict, list)):
            raise FieldError(f'{path}: expected a string, got {value!r}')
        text = value if isinstance(value, str) else str(value)
        if bound and len(text) > bound:
            raise FieldError(f'{path}: longer than its bound of {bound} characters')
        return text
    if base == 'bool':
        if not isinstance(value, bool):
            raise FieldError(f'{path}: expected true or false, got {value!r}')
        return value
    if base in ('float32', 'float64'):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise FieldError(f'{path}: expected a number ({base}), got {value!r}')
        return float(value)
    return _int(value, base, path)


def _value(desc: Any, value: Any, path: str, stamps: list[StampSetter],
           setter: Callable[[Any], None]) -> None:
    kind, rest = desc
    if kind == Nodetype.BASE:
        setter(_base(value, rest[0], rest[1], path))
        return
    if kind == Nodetype.NAME:
        if rest == 'std_msgs/msg/Header' and value == 'auto':
            header = msgs.get_message(rest)()

            def stamp(now: Any) -> None:
                header.stamp = now

            stamps.append(stamp)
            setter(header)
            return
        if rest == 'builtin_interfaces/msg/Time' and value == 'now':
            stamps.append(setter)
            setter(msgs.get_message(rest)())
            return
        sub = msgs.get_message(rest)()
        _fill(sub, value, path, stamps)
        setter(sub)
        return
    sub_desc, length = rest
    if not isinstance(value, (list, tuple)):
        raise FieldError(f'{path}: expected a list, got {value!r}')
    if kind == Nodetype.ARRAY and len(value) != length:
        raise FieldError(f'{path}: expected exactly {length} items, got {len(value)}')
    if kind == Nodetype.SEQUENCE and length and len(value) > length:
        raise FieldError(f'{path}: at most {length} items, got {len(value)}')
    items: list[Any] = [None] * len(value)

    def item_setter(i: int) -> Callable[[Any], None]:
        return lambda v: items.__setitem__(i, v)

    for i, item in enumerate(value):
        _value(sub_desc, item, f'{path}[{i}]', stamps, item_setter(i))
    setter(items)   # the message class makes primitive lists numpy arrays


def _field_setter(msg: Any, name: str) -> Callable[[Any], None]:
    return lambda v: setattr(msg, name, v)


def _fill(msg: Any, values: Any, path: str, stamps: list[StampSetter]) -> None:
    typename = msgs.type_of(msg)
    if not isinstance(values, dict):
        raise FieldError(f'{path or typename}: expected a mapping of the fields of {typename}, '
                         f'got {values!r}')
    fields = dict(fields_of(typename))
    for name, value in values.items():
        where = f'{path}.{name}' if path else str(name)
        if name not in fields:
            raise FieldError(f'{where}: {typename} has no such field (it has: '
                             f'{", ".join(fields) or "none"})')
        _value(fields[name], value, where, stamps, _field_setter(msg, name))


def set_fields(msg: Any, values: dict[str, Any]) -> list[StampSetter]:
    """Fill msg from a mapping (rosidl_runtime_py.set_message_fields with expand_header_auto
    and expand_time_now): FieldError names the field and the reason. Returns the setters of the
    'auto' headers' stamps and 'now' times, to be called with the time of each publish."""
    stamps: list[StampSetter] = []
    _fill(msg, values, '', stamps)
    return stamps


__all__ = ['DEFAULT_TRUNCATE_LENGTH', 'FieldError', 'fields_of', 'parse_values', 'set_fields',
           'to_ordereddict', 'to_yaml']
