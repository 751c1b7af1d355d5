"""rclpy.time.Time and rclpy.clock: system, steady and ROS clocks (ROS clock follows /clock with
use_sim_time)."""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Callable
from enum import IntEnum
from typing import TYPE_CHECKING, Any

from .. import msgs
from .duration import Duration

if TYPE_CHECKING:
    from .context import Context


class ClockType(IntEnum):
    UNINITIALIZED = 0
    ROS_TIME = 1
    SYSTEM_TIME = 2
    STEADY_TIME = 3


class Time:
    def __init__(self, *, seconds: float = 0, nanoseconds: int = 0,
                 clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        total = int(seconds * 1_000_000_000) + int(nanoseconds)
        if total < 0:
            raise ValueError('Time cannot be negative')
        self._ns = total
        self.clock_type = clock_type

    @property
    def nanoseconds(self) -> int:
        return self._ns

    def seconds_nanoseconds(self) -> tuple[int, int]:
        return divmod(self._ns, 1_000_000_000)

    def to_msg(self) -> Any:
        sec, nsec = divmod(self._ns, 1_000_000_000)
        return msgs.get_message('builtin_interfaces/msg/Time')(sec=sec, nanosec=nsec)

    @classmethod
    def from_msg(cls, msg: Any, clock_type: ClockType = ClockType.ROS_TIME) -> Time:
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec, clock_type=clock_type)

    def __add__(self, other: Duration) -> Time:
        return Time(nanoseconds=self._ns + other.nanoseconds, clock_type=self.clock_type)

    def __sub__(self, other: Time | Duration) -> Any:
        if isinstance(other, Time):
            if other.clock_type != self.clock_type:
                raise TypeError("Can't subtract times with different clock types")
            return Duration(nanoseconds=self._ns - other._ns)
        return Time(nanoseconds=self._ns - other.nanoseconds, clock_type=self.clock_type)

    def _cmp(self, other: Time) -> int:
        if not isinstance(other, Time):
            raise TypeError(f'cannot compare Time with {type(other).__name__}')
        if other.clock_type != self.clock_type:
            raise TypeError("Can't compare times with different clock types")
        return (self._ns > other._ns) - (self._ns < other._ns)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Time) and self._cmp(other) == 0

    def __lt__(self, other: Time) -> bool:
        return self._cmp(other) < 0

    def __le__(self, other: Time) -> bool:
        return self._cmp(other) <= 0

    def __gt__(self, other: Time) -> bool:
        return self._cmp(other) > 0

    def __ge__(self, other: Time) -> bool:
        return self._cmp(other) >= 0

    def __hash__(self) -> int:
        return hash((self._ns, self.clock_type))

    def __repr__(self) -> str:
        return f'Time(nanoseconds={self._ns}, clock_type={self.clock_type.name})'


class Clock:
    """rclpy.clock.Clock. A ROS_TIME clock with ROS time active (use_sim_time) reads the latest
    override (/clock), and zero before the first one, as rclpy's does: timers on it do not fire
    until /clock arrives. Inactive, it reads the system time."""

    def __init__(self, *, clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        self.clock_type = clock_type
        self._ros_time_active = False
        self._ros_time_ns = 0   # the latest override; 0: none yet ("uninitialized" in rcl)
        self._changed = threading.Condition()
        # called (any thread) whenever what now() reads changes other than by the passing of
        # wall time: a node's clock wakes its executor with it, so sim-time timers need no polling
        self._on_change: list[Callable[[], None]] = []
        self.wakes_executor = False     # a node's clock: its changes wake the node's executor

    def now(self) -> Time:
        return Time(nanoseconds=self._now_ns(), clock_type=self.clock_type)

    def _now_ns(self) -> int:
        """now().nanoseconds without a Time object (timers ask at every executor wake-up)."""
        if self.clock_type == ClockType.STEADY_TIME:
            return _time.monotonic_ns()
        if self.clock_type == ClockType.ROS_TIME and self._ros_time_active:
            return self._ros_time_ns
        return _time.time_ns()

    @property
    def ros_time_is_active(self) -> bool:
        return self.clock_type == ClockType.ROS_TIME and self._ros_time_active

    def _set_ros_time_is_active(self, enabled: bool) -> None:
        """rclpy's TimeSource calls this when use_sim_time changes (the override is kept)."""
        with self._changed:
            self._ros_time_active = bool(enabled)
            self._changed.notify_all()
        self._notify_change()

    def set_ros_time_override(self, time: Time) -> None:
        """What /clock sets (it is read only while ROS time is active)."""
        self._set_ros_time_ns(int(time.nanoseconds))

    def _set_ros_time_ns(self, nanoseconds: int) -> None:
        with self._changed:
            self._ros_time_ns = nanoseconds
            self._changed.notify_all()
        self._notify_change()

    def _notify_change(self) -> None:
        for callback in list(self._on_change):
            callback()

    def sleep_for(self, rel_time: Duration, context: Context | None = None) -> bool:
        return self.sleep_until(self.now() + rel_time, context)

    def sleep_until(self, until: Time, context: Context | None = None) -> bool:
        """As rclpy's: True once `until` is reached on this clock, False when the context shuts
        down first (NotInitializedException, as RuntimeError here, if it is not initialized)."""
        from .context import get_default_context
        context = context or get_default_context()
        if not context.ok():
            raise RuntimeError('sleep_until: the context is not initialized or was shut down')
        while True:
            if not context.ok():
                return False
            remaining = until.nanoseconds - self.now().nanoseconds
            if remaining <= 0:
                return True
            if not self.ros_time_is_active:
                _time.sleep(min(remaining / 1e9, 0.1))   # ROS time may turn on meanwhile
            else:
                with self._changed:
                    self._changed.wait(min(remaining / 1e9, 0.1))


class ROSClock(Clock):
    def __init__(self) -> None:
        super().__init__(clock_type=ClockType.ROS_TIME)
