"""rclpy logging subset: RcutilsLogger-like loggers printing in ROS 2's console format, and
sending each record to /rosout through the node whose logger it is (see add_rosout_sink)."""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable
from enum import IntEnum
from typing import Any


class LoggingSeverity(IntEnum):
    UNSET = 0
    DEBUG = 10
    INFO = 20
    WARN = 30
    ERROR = 40
    FATAL = 50


_LEVEL_NAMES = {'debug': LoggingSeverity.DEBUG, 'info': LoggingSeverity.INFO,
                'warn': LoggingSeverity.WARN, 'warning': LoggingSeverity.WARN,
                'error': LoggingSeverity.ERROR, 'fatal': LoggingSeverity.FATAL}
_default_level = LoggingSeverity.INFO
_lock = threading.Lock()

# rcl's rosout output handler: a record of logger `name` (or of a child logger made from it with
# get_child) is also handed to the sink registered under `name`, the node that owns that logger,
# which publishes it as rcl_interfaces/msg/Log on /rosout. sink(stamp_ns, level, name, msg,
# file, function, line). Node registers one unless enable_rosout=False.
RosoutSink = Callable[[int, int, str, str, str, str, int], None]
_rosout_sinks: dict[str, RosoutSink] = {}
_in_sink = threading.local()   # a record logged while one is being sent is not sent (no loops)
_THIS_FILE = os.path.normcase(os.path.abspath(__file__))


def add_rosout_sink(name: str, sink: RosoutSink) -> None:
    _rosout_sinks[name] = sink


def remove_rosout_sink(name: str, sink: RosoutSink) -> None:
    if _rosout_sinks.get(name) is sink:
        del _rosout_sinks[name]


def _caller() -> tuple[str, str, int]:
    """(file, function, line) of the first frame outside this module, as rclpy's CallerId."""
    frame = sys._getframe(1)
    while frame.f_back is not None and os.path.normcase(frame.f_code.co_filename) == _THIS_FILE:
        frame = frame.f_back
    return os.path.abspath(frame.f_code.co_filename), frame.f_code.co_name, frame.f_lineno


def set_default_level(level: str | int) -> None:
    global _default_level
    _default_level = (_LEVEL_NAMES[level.lower()] if isinstance(level, str)
                      else LoggingSeverity(level))


# rclpy's logging options (rcutils_logger.supported_filters' parameters, and name)
_LOG_OPTIONS = {'once', 'throttle_duration_sec', 'throttle_time_source_type', 'skip_first', 'name'}


class RcutilsLogger:
    def __init__(self, name: str = '') -> None:
        self.name = name
        self._parent: RcutilsLogger | None = None   # set by get_child: /rosout goes through it
        self._level: LoggingSeverity | None = None
        self._once: set[tuple[str, int]] = set()
        self._last: dict[tuple[str, int], float] = {}

    def get_child(self, name: str) -> RcutilsLogger:
        child = RcutilsLogger(f'{self.name}.{name}' if self.name else name)
        child._parent = self if self.name else None
        return child

    def _rosout_sink(self) -> RosoutSink | None:
        logger: RcutilsLogger | None = self
        while logger is not None:
            sink = _rosout_sinks.get(logger.name)
            if sink is not None:
                return sink
            logger = logger._parent
        return None

    def set_level(self, level: LoggingSeverity | int) -> None:
        self._level = LoggingSeverity(level)

    def get_effective_level(self) -> LoggingSeverity:
        return self._level or _default_level

    def is_enabled_for(self, severity: LoggingSeverity | int) -> bool:
        return severity >= self.get_effective_level()

    def log(self, message: Any, severity: LoggingSeverity | int, **kwargs: Any) -> bool:
        """rclpy's keywords: once, throttle_duration_sec (with throttle_time_source_type: only
        rclpy's default, the steady clock), skip_first, name; any other is a TypeError with
        rclpy's text (checked at every call, where rclpy checks only enabled ones)."""
        unknown = set(kwargs) - _LOG_OPTIONS
        if unknown:
            raise TypeError(f'parameter "{sorted(unknown)[0]}" is not one of the recognized '
                            f'logging options "{sorted(_LOG_OPTIONS - {"name"})}"')
        source = kwargs.get('throttle_time_source_type', 'RCUTILS_STEADY_TIME')
        if source != 'RCUTILS_STEADY_TIME':
            raise NotImplementedError(f'log(throttle_time_source_type={source!r}): the bundled '
                                      'runtime throttles on the steady clock only')
        once = bool(kwargs.get('once', False))
        throttle_duration_sec = kwargs.get('throttle_duration_sec')
        skip_first = bool(kwargs.get('skip_first', False))
        name = str(kwargs.get('name', self.name))
        severity = LoggingSeverity(severity)
        if not self.is_enabled_for(severity):
            return False
        if once or throttle_duration_sec or skip_first:
            # like rclpy, `once` and throttling are per call site, not per logger
            caller = sys._getframe(2)
            key = (caller.f_code.co_filename, caller.f_lineno)
            if once:
                if key in self._once:
                    return False
                self._once.add(key)
            now = time.monotonic()
            last = self._last.get(key)
            if last is None and skip_first:
                self._last[key] = now
                return False
            if throttle_duration_sec and last is not None and now - last < throttle_duration_sec:
                return False
            self._last[key] = now
        stamp_ns = time.time_ns()
        seconds, nanoseconds = divmod(stamp_ns, 1_000_000_000)
        line = f'[{severity.name}] [{seconds}.{nanoseconds:09d}] [{name}]: {message}\n'
        with _lock:
            sys.stderr.write(line)
            sys.stderr.flush()
        sink = self._rosout_sink()
        if sink is not None and not getattr(_in_sink, 'active', False):
            _in_sink.active = True
            try:
                sink(stamp_ns, int(severity), name, str(message), *_caller())
            except Exception:  # noqa: BLE001 - /rosout never breaks logging (rcl just drops it)
                pass
            finally:
                _in_sink.active = False
        return True

    def debug(self, message: Any, **kwargs: Any) -> bool:
        return self.log(message, LoggingSeverity.DEBUG, **kwargs)

    def info(self, message: Any, **kwargs: Any) -> bool:
        return self.log(message, LoggingSeverity.INFO, **kwargs)

    def warning(self, message: Any, **kwargs: Any) -> bool:
        return self.log(message, LoggingSeverity.WARN, **kwargs)

    warn = warning

    def error(self, message: Any, **kwargs: Any) -> bool:
        return self.log(message, LoggingSeverity.ERROR, **kwargs)

    def fatal(self, message: Any, **kwargs: Any) -> bool:
        return self.log(message, LoggingSeverity.FATAL, **kwargs)


def get_logger(name: str) -> RcutilsLogger:
    return RcutilsLogger(name)
