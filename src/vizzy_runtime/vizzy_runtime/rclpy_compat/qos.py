"""rclpy.qos subset: profiles and policies, mapped one to one onto DDS QoS
(vizzy_runtime.dds.QoS)."""

from __future__ import annotations

from enum import IntEnum

from .. import dds
from .duration import Duration


class ReliabilityPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2


class DurabilityPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class HistoryPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2


class LivelinessPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3


# rclpy's older aliases, still used in examples.
QoSReliabilityPolicy = ReliabilityPolicy
QoSDurabilityPolicy = DurabilityPolicy
QoSHistoryPolicy = HistoryPolicy
QoSLivelinessPolicy = LivelinessPolicy


class QoSProfile:
    """rclpy.qos.QoSProfile: history + depth are required unless history is KEEP_ALL."""

    def __init__(self, *, depth: int | None = None,
                 history: HistoryPolicy = HistoryPolicy.KEEP_LAST,
                 reliability: ReliabilityPolicy = ReliabilityPolicy.RELIABLE,
                 durability: DurabilityPolicy = DurabilityPolicy.VOLATILE,
                 liveliness: LivelinessPolicy = LivelinessPolicy.SYSTEM_DEFAULT,
                 deadline: Duration | None = None, lifespan: Duration | None = None,
                 liveliness_lease_duration: Duration | None = None,
                 avoid_ros_namespace_conventions: bool = False) -> None:
        if avoid_ros_namespace_conventions:   # rclpy takes it; the topic names here are always
            raise NotImplementedError(    # ROS-mangled (rt/...), as rmw's default
                'QoSProfile(avoid_ros_namespace_conventions=True): not supported by the bundled '
                'runtime')
        if depth is None and history == HistoryPolicy.KEEP_LAST:
            raise ValueError('QoSProfile: depth is required with KEEP_LAST history')
        if depth is not None and depth < 0:
            raise ValueError(f'QoSProfile: depth must be >= 0, got {depth}')
        self.depth = depth or 0
        self.history = HistoryPolicy(history)
        self.reliability = ReliabilityPolicy(reliability)
        self.durability = DurabilityPolicy(durability)
        self.liveliness = LivelinessPolicy(liveliness)
        self.deadline = deadline or Duration()
        self.lifespan = lifespan or Duration()
        self.liveliness_lease_duration = liveliness_lease_duration or Duration()

    def to_dds(self) -> dds.QoS:
        return dds.QoS(
            reliable=self.reliability != ReliabilityPolicy.BEST_EFFORT,
            transient_local=self.durability == DurabilityPolicy.TRANSIENT_LOCAL,
            keep_all=self.history == HistoryPolicy.KEEP_ALL,
            depth=self.depth or 1,
            deadline_ns=self.deadline.nanoseconds or None,
            lifespan_ns=self.lifespan.nanoseconds or None,
            liveliness_manual=self.liveliness == LivelinessPolicy.MANUAL_BY_TOPIC,
            liveliness_lease_ns=self.liveliness_lease_duration.nanoseconds or None,
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, QoSProfile) and self.to_dds() == other.to_dds()

    def __repr__(self) -> str:
        return (f'QoSProfile(history={self.history.name}, depth={self.depth}, '
                f'reliability={self.reliability.name}, durability={self.durability.name})')


def as_profile(qos: QoSProfile | int) -> QoSProfile:
    """rclpy accepts a bare depth where a profile is expected."""
    if isinstance(qos, QoSProfile):
        return qos
    if isinstance(qos, int) and not isinstance(qos, bool):
        return QoSProfile(depth=qos)
    raise TypeError(f'expected a QoSProfile or a history depth, got {qos!r}')


qos_profile_sensor_data = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
qos_profile_system_default = QoSProfile(depth=10)
qos_profile_services_default = QoSProfile(depth=10)
qos_profile_parameters = QoSProfile(depth=1000)
qos_profile_parameter_events = QoSProfile(depth=1000)
qos_profile_clock = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
# rcl's rcl_qos_profile_rosout_default (the /rosout publisher every node has)
qos_profile_rosout_default = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                                        durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                        lifespan=Duration(seconds=10))
