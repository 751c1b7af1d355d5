"""rclpy.parameter.Parameter and the rcl_interfaces messages nodes use to describe parameters."""

from __future__ import annotations

from enum import IntEnum
from typing import Any

import numpy as np

from .. import msgs

ParameterDescriptor = msgs.get_message('rcl_interfaces/msg/ParameterDescriptor')
ParameterType = msgs.get_message('rcl_interfaces/msg/ParameterType')
ParameterValue = msgs.get_message('rcl_interfaces/msg/ParameterValue')
SetParametersResult = msgs.get_message('rcl_interfaces/msg/SetParametersResult')
FloatingPointRange = msgs.get_message('rcl_interfaces/msg/FloatingPointRange')
IntegerRange = msgs.get_message('rcl_interfaces/msg/IntegerRange')


class Parameter:
    class Type(IntEnum):
        NOT_SET = 0
        BOOL = 1
        INTEGER = 2
        DOUBLE = 3
        STRING = 4
        BYTE_ARRAY = 5
        BOOL_ARRAY = 6
        INTEGER_ARRAY = 7
        DOUBLE_ARRAY = 8
        STRING_ARRAY = 9

        @classmethod
        def from_parameter_value(cls, value: Any) -> Parameter.Type:
            if value is None:
                return cls.NOT_SET
            if isinstance(value, (bool, np.bool_)):
                return cls.BOOL
            if isinstance(value, (int, np.integer)):
                return cls.INTEGER
            if isinstance(value, (float, np.floating)):
                return cls.DOUBLE
            if isinstance(value, str):
                return cls.STRING
            if isinstance(value, bytes):
                return cls.BYTE_ARRAY
            if isinstance(value, (list, tuple, np.ndarray)):
                items = list(value)
                if all(isinstance(v, (bool, np.bool_)) for v in items) and items:
                    return cls.BOOL_ARRAY
                if all(isinstance(v, (int, np.integer)) and not isinstance(v, bool)
                       for v in items) and items:
                    return cls.INTEGER_ARRAY
                if all(isinstance(v, (float, int, np.floating)) and not isinstance(v, bool)
                       for v in items) and items:
                    return cls.DOUBLE_ARRAY
                if all(isinstance(v, str) for v in items) and items:
                    return cls.STRING_ARRAY
                if not items:
                    raise TypeError('an empty list has no parameter type: declare it with a typed '
                                    'descriptor')
            raise TypeError(f'value {value!r} has no ROS parameter type')

        def check(self, value: Any) -> bool:
            if self == Parameter.Type.NOT_SET:
                return value is None
            try:
                return Parameter.Type.from_parameter_value(value) == self or (
                    self == Parameter.Type.DOUBLE_ARRAY
                    and Parameter.Type.from_parameter_value(value) == Parameter.Type.INTEGER_ARRAY)
            except TypeError:
                return isinstance(value,
                                  (list, tuple)) and not value and self >= Parameter.Type.BYTE_ARRAY

    def __init__(self, name: str, type_: Parameter.Type | None = None, value: Any = None) -> None:
        if type_ is None:
            type_ = Parameter.Type.from_parameter_value(value)
        type_ = Parameter.Type(type_)
        if not type_.check(value):
            raise TypeError(f"parameter '{name}': value {value!r} is not of type {type_.name}")
        if type_ == Parameter.Type.DOUBLE_ARRAY and value is not None:
            value = [float(v) for v in value]
        self._name = name
        self._type = type_
        self._value = value

    @property
    def name(self) -> str:
        return self._name

    @property
    def type_(self) -> Parameter.Type:
        return self._type

    @property
    def value(self) -> Any:
        return self._value

    def get_parameter_value(self) -> Any:
        msg = ParameterValue(type=int(self._type))
        field = {1: 'bool_value', 2: 'integer_value', 3: 'double_value', 4: 'string_value',
                 5: 'byte_array_value', 6: 'bool_array_value', 7: 'integer_array_value',
                 8: 'double_array_value', 9: 'string_array_value'}.get(int(self._type))
        if field:
            value = self._value
            if field in ('byte_array_value', 'bool_array_value', 'integer_array_value',
                         'double_array_value'):
                dtype = {'byte_array_value': np.uint8, 'bool_array_value': np.bool_,
                         'integer_array_value': np.int64, 'double_array_value': np.float64}[field]
                value = np.asarray(list(value), dtype=dtype)
            setattr(msg, field, value)
        return msg

    def to_parameter_msg(self) -> Any:
        return msgs.get_message('rcl_interfaces/msg/Parameter')(
            name=self._name, value=self.get_parameter_value())

    @classmethod
    def from_parameter_msg(cls, param_msg: Any) -> Parameter:
        return cls(param_msg.name, Parameter.Type(param_msg.value.type),
                   parameter_value_to_python(param_msg.value))

    def __repr__(self) -> str:
        return f'Parameter({self._name!r}, {self._type.name}, {self._value!r})'


def parameter_value_to_python(parameter_value: Any) -> Any:
    value = parameter_value
    t = Parameter.Type(value.type)
    if t == Parameter.Type.NOT_SET:
        return None
    field = ['', 'bool_value', 'integer_value', 'double_value', 'string_value', 'byte_array_value',
             'bool_array_value', 'integer_array_value', 'double_array_value',
             'string_array_value'][t]
    out = getattr(value, field)
    if isinstance(out, np.ndarray):
        out = bytes(out) if t == Parameter.Type.BYTE_ARRAY else out.tolist()
    return out
