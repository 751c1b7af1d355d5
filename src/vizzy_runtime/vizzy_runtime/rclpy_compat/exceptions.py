"""rclpy.exceptions subset."""


class ROSInterruptException(Exception):
    """Raised when the context is shut down while waiting."""


class ExternalShutdownException(Exception):
    """Raised by executors when the context was shut down from outside (signal or shutdown())."""


class ParameterException(Exception):
    def __init__(self, message: str, *parameters: object) -> None:
        super().__init__(message)
        self.parameters = parameters


class ParameterNotDeclaredException(ParameterException):
    def __init__(self, name: str) -> None:
        super().__init__(f"parameter '{name}' has not been declared", name)


class ParameterAlreadyDeclaredException(ParameterException):
    def __init__(self, name: str) -> None:
        super().__init__(f"parameter '{name}' has already been declared", name)


class InvalidParameterTypeException(ParameterException):
    def __init__(self, name: str, reason: str) -> None:
        super().__init__(f"parameter '{name}': {reason}", name)


class InvalidParameterValueException(ParameterException):
    def __init__(self, name: str, value: object, reason: str) -> None:
        super().__init__(f"parameter '{name}' rejected value {value!r}: {reason}", name, value)
        self.reason = reason


class ParameterImmutableException(ParameterException):
    def __init__(self, name: str) -> None:
        super().__init__(f"parameter '{name}' is read-only", name)


class ParameterUninitializedException(ParameterException):
    def __init__(self, name: str) -> None:
        super().__init__(f"parameter '{name}' is declared without a value and was never set", name)
