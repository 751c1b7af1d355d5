"""The one seam between our nodes and ROS 2.

With ROS 2 Jazzy sourced, everything here is the real rclpy and the real generated message
classes. Without it, the same names come from the bundled runtime (vizzy_runtime.rclpy_compat,
on Cyclone DDS, wire-compatible with rmw_cyclonedds_cpp). No other module makes this choice.

Nodes write:
    from vizzy_runtime.ros import rclpy, Node, message, qos_profile_sensor_data, ...
    Image = message('sensor_msgs/msg/Image')

VIZZY_RUNTIME chooses: unset, the real rclpy when importable, else the bundled runtime;
`bundled`, the bundled runtime even where rclpy is importable; `ros`, the real rclpy or an
ImportError saying why (the real-rclpy test tier and .venv-ros use it, so they can never test the
bundled runtime by mistake).
"""

from __future__ import annotations

import importlib
import os
from typing import Any

RUNTIME_CHOICE = os.environ.get('VIZZY_RUNTIME', '')
if RUNTIME_CHOICE not in ('', 'bundled', 'ros'):
    raise ImportError(f'VIZZY_RUNTIME={RUNTIME_CHOICE!r}: expected "bundled", "ros" or unset')

USING_REAL_ROS = False
if RUNTIME_CHOICE != 'bundled':
    try:
        import rclpy
        USING_REAL_ROS = True
    except ImportError as exc:
        if RUNTIME_CHOICE == 'ros':
            raise ImportError(f'VIZZY_RUNTIME=ros but the real rclpy does not import ({exc}); '
                              'use .venv-ros/bin/python or source ROS 2 Jazzy') from None

if USING_REAL_ROS:
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        ParameterType,
        SetParametersResult,
    )
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rclpy.exceptions import (
        InvalidHandle,
        InvalidParameterTypeException,
        InvalidParameterValueException,
        ParameterException,
    )
    from rclpy.executors import (
        ExternalShutdownException,
        MultiThreadedExecutor,
        SingleThreadedExecutor,
    )
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy_impl
    RCLError = _rclpy_impl.RCLError  # e.g. publishing on a context that was shut down
    from rclpy.node import Node
    from rclpy.parameter import Parameter, parameter_value_to_python
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
        qos_profile_system_default,
    )
    from rclpy.time import Time
else:
    from . import rclpy_compat as rclpy
    from .rclpy_compat.context import Context
    from .rclpy_compat.duration import Duration
    from .rclpy_compat.exceptions import (
        InvalidHandle,
        InvalidParameterTypeException,
        InvalidParameterValueException,
        ParameterException,
        RCLError,
    )
    from .rclpy_compat.executors import (
        ExternalShutdownException,
        MultiThreadedExecutor,
        SingleThreadedExecutor,
    )
    from .rclpy_compat.node import Node
    from .rclpy_compat.parameter import (
        FloatingPointRange,
        IntegerRange,
        Parameter,
        ParameterDescriptor,
        ParameterType,
        SetParametersResult,
        parameter_value_to_python,
    )
    from .rclpy_compat.parameter_client import AsyncParameterClient
    from .rclpy_compat.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
        qos_profile_system_default,
    )
    from .rclpy_compat.time import Time

# /tf_static and other latched topics use this profile in ROS 2.
qos_profile_latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                 reliability=ReliabilityPolicy.RELIABLE,
                                 history=HistoryPolicy.KEEP_LAST)


def warm_up() -> None:
    """Before a zygote forks its node (cli.cmd_run --zygote): what the runtime can prepare for a
    node's construction without joining the network (bundled: rclpy_compat/warm_up.py; rclpy:
    nothing)."""
    if not USING_REAL_ROS:
        from .rclpy_compat.warm_up import warm_up as _warm_up
        _warm_up()


def message(typename: str) -> Any:
    """The message class for 'pkg/msg/Type' (real generated class, or the bundled runtime's)."""
    parts = typename.replace('.', '/').split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3:
        raise ValueError(f'not a message type name: {typename!r}')
    if USING_REAL_ROS:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    from .msgs import get_message
    return get_message('/'.join(parts))


__all__ = [
    'USING_REAL_ROS', 'AsyncParameterClient', 'Context', 'Duration', 'DurabilityPolicy',
    'ExternalShutdownException', 'FloatingPointRange', 'HistoryPolicy', 'IntegerRange',
    'InvalidParameterTypeException', 'InvalidHandle', 'InvalidParameterValueException',
    'MultiThreadedExecutor', 'Node', 'ParameterException', 'Parameter', 'ParameterDescriptor',
    'ParameterType', 'QoSProfile', 'RCLError', 'ReliabilityPolicy', 'SetParametersResult',
    'SingleThreadedExecutor', 'Time', 'message', 'parameter_value_to_python',
    'qos_profile_latched', 'qos_profile_sensor_data', 'qos_profile_system_default', 'rclpy',
    'warm_up',
]
