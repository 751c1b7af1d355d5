"""rclpy.exceptions subset, with rclpy's (Jazzy) names, constructor arguments and messages, so
that code catching or reading them behaves the same on either runtime."""

from __future__ import annotations

from typing import Any


class ROSInterruptException(Exception):
    """Raised when the context is shut down while waiting."""


class ExternalShutdownException(Exception):
    """Raised by executors when the context was shut down from outside (signal or shutdown())."""


class RCLError(RuntimeError):
    """rclpy._rclpy_pybind11.RCLError: an rcl call failed, e.g. publishing on a context that was
    shut down ("Failed to publish: publisher's context is invalid")."""


class InvalidHandle(RuntimeError):
    """rclpy.exceptions.InvalidHandle: using an entity after it was destroyed."""


class ParameterException(Exception):
    """Base exception for parameter-related errors (str: '<error_msg>: <parameters>')."""

    def __init__(self, error_msg: str, parameters: Any) -> None:
        super().__init__(f'{error_msg}: {parameters}')
        self.parameters = parameters


class ParameterNotDeclaredException(ParameterException):
    def __init__(self, parameters: Any) -> None:
        super().__init__('Invalid access to undeclared parameter(s)', parameters)


class ParameterAlreadyDeclaredException(ParameterException):
    def __init__(self, parameters: Any) -> None:
        super().__init__('Parameter(s) already declared', parameters)


class InvalidParameterException(ParameterException):
    def __init__(self, parameter_name: str) -> None:
        super().__init__('Invalid parameter name', parameter_name)


class InvalidParameterTypeException(ParameterException):
    """desired_parameter: the refused Parameter; expected_type: the declared type's name."""

    def __init__(self, desired_parameter: Any, expected_type: Any) -> None:
        from .parameter import Parameter
        try:
            got = Parameter.Type.from_parameter_value(desired_parameter.value).name
        except TypeError:
            got = desired_parameter.type_.name
        super().__init__(
            f"Trying to set parameter '{desired_parameter.name}' to '{desired_parameter.value}'"
            f" of type '{got}', expecting type '{expected_type}'", desired_parameter.name)


class InvalidParameterValueException(ParameterException):
    """Refused by an on-set callback or by the descriptor (range); reason says why."""

    def __init__(self, parameter: str, value: Any, reason: str) -> None:
        super().__init__(f'Invalid parameter value ({value}) for parameter. Reason: {reason}',
                         parameter)
        self.reason = reason


class ParameterImmutableException(ParameterException):
    def __init__(self, parameter_name: str) -> None:
        super().__init__('Attempted to modify read-only parameter', parameter_name)


class ParameterUninitializedException(ParameterException):
    def __init__(self, parameter_name: str) -> None:
        super().__init__(f"The parameter '{parameter_name}' is not initialized", parameter_name)
