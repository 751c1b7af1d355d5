"""rclpy.duration.Duration."""

from __future__ import annotations

from typing import Any

from .. import msgs


class Duration:
    def __init__(self, *, seconds: float = 0, nanoseconds: int = 0) -> None:
        self._ns = int(seconds * 1_000_000_000) + int(nanoseconds)

    @property
    def nanoseconds(self) -> int:
        return self._ns

    def to_msg(self) -> Any:
        sec, nsec = divmod(self._ns, 1_000_000_000)
        return msgs.get_message('builtin_interfaces/msg/Duration')(sec=sec, nanosec=nsec)

    @classmethod
    def from_msg(cls, msg: Any) -> Duration:
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Duration) and self._ns == other._ns

    def __lt__(self, other: Duration) -> bool:
        return self._ns < other._ns

    def __le__(self, other: Duration) -> bool:
        return self._ns <= other._ns

    def __gt__(self, other: Duration) -> bool:
        return self._ns > other._ns

    def __ge__(self, other: Duration) -> bool:
        return self._ns >= other._ns

    def __hash__(self) -> int:
        return hash(self._ns)

    def __add__(self, other: Duration) -> Duration:
        return Duration(nanoseconds=self._ns + other.nanoseconds)

    def __sub__(self, other: Duration) -> Duration:
        return Duration(nanoseconds=self._ns - other.nanoseconds)

    def __mul__(self, factor: float) -> Duration:
        return Duration(nanoseconds=int(self._ns * factor))

    def __repr__(self) -> str:
        return f'Duration(nanoseconds={self._ns})'
