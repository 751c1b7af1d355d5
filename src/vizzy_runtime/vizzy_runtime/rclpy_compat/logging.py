"""rclpy logging subset: RcutilsLogger-like loggers printing in ROS 2's console format."""

from __future__ import annotations

import sys
import threading
import time
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


def set_default_level(level: str | int) -> None:
    global _default_level
    _default_level = _LEVEL_NAMES[level.lower()] if isinstance(level, str) else LoggingSeverity(level)


class RcutilsLogger:
    def __init__(self, name: str = '') -> None:
        self.name = name
        self._level: LoggingSeverity | None = None
        self._once: set[tuple[str, int]] = set()
        self._last: dict[tuple[str, int], float] = {}

    def get_child(self, name: str) -> 'RcutilsLogger':
        return RcutilsLogger(f'{self.name}.{name}' if self.name else name)

    def set_level(self, level: LoggingSeverity | int) -> None:
        self._level = LoggingSeverity(level)

    def get_effective_level(self) -> LoggingSeverity:
        return self._level or _default_level

    def is_enabled_for(self, severity: LoggingSeverity | int) -> bool:
        return severity >= self.get_effective_level()

    def log(self, message: Any, severity: LoggingSeverity | int, *, once: bool = False,
            throttle_duration_sec: float | None = None, skip_first: bool = False, **_: Any) -> bool:
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
        stamp = time.time()
        line = f'[{severity.name}] [{stamp:.9f}] [{self.name}]: {message}\n'
        with _lock:
            sys.stderr.write(line)
            sys.stderr.flush()
        return True

    def debug(self, message: Any, **kw: Any) -> bool:
        return self.log(message, LoggingSeverity.DEBUG, **kw)

    def info(self, message: Any, **kw: Any) -> bool:
        return self.log(message, LoggingSeverity.INFO, **kw)

    def warning(self, message: Any, **kw: Any) -> bool:
        return self.log(message, LoggingSeverity.WARN, **kw)

    warn = warning

    def error(self, message: Any, **kw: Any) -> bool:
        return self.log(message, LoggingSeverity.ERROR, **kw)

    def fatal(self, message: Any, **kw: Any) -> bool:
        return self.log(message, LoggingSeverity.FATAL, **kw)


def get_logger(name: str) -> RcutilsLogger:
    return RcutilsLogger(name)
