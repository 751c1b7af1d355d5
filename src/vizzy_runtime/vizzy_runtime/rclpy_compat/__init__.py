"""The bundled rclpy: the subset of rclpy's API our nodes use, on Cyclone DDS (see vizzy_runtime.ros)."""

from __future__ import annotations

import signal
import threading
from typing import Any

from .context import Context, get_default_context
from .executors import Executor, SingleThreadedExecutor
from .node import Node

_global_executor: Executor | None = None


def _on_signal(signum: int, frame: Any) -> None:
    """SIGINT/SIGTERM, like rclpy's handler: shut the context down so spin returns between
    callbacks. A KeyboardInterrupt raised at an arbitrary point (inside a callback, a C call or
    the clean-up itself) could otherwise kill the process without its clean-up. A second signal
    while the first is being honoured raises KeyboardInterrupt, for a node that hangs."""
    context = get_default_context()
    if context.ok():
        context.request_shutdown()
    else:
        raise KeyboardInterrupt


def init(*, args: list[str] | None = None, context: Context | None = None,
         domain_id: int | None = None, **_ignored: Any) -> None:
    """rclpy.init: parse --ros-args (from sys.argv when args is None); SIGINT and SIGTERM end spin."""
    import sys
    (context or get_default_context()).init(sys.argv if args is None else args, domain_id)
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(sig) in (signal.SIG_DFL, signal.default_int_handler, None):
                signal.signal(sig, _on_signal)


def ok(*, context: Context | None = None) -> bool:
    return (context or get_default_context()).ok()


def shutdown(*, context: Context | None = None, uninstall_handlers: bool | None = None) -> None:
    (context or get_default_context()).shutdown()


def try_shutdown(*, context: Context | None = None, uninstall_handlers: bool | None = None) -> None:
    (context or get_default_context()).try_shutdown()


def create_node(node_name: str, **kwargs: Any) -> Node:
    return Node(node_name, **kwargs)


def get_global_executor() -> Executor:
    global _global_executor
    if _global_executor is None:
        _global_executor = SingleThreadedExecutor()
    return _global_executor


def spin(node: Node, executor: Executor | None = None) -> None:
    executor = executor or get_global_executor()
    executor.add_node(node)
    try:
        while executor.context.ok():
            executor.spin_once()
    finally:
        executor.remove_node(node)


def spin_once(node: Node, *, executor: Executor | None = None, timeout_sec: float | None = None) -> None:
    executor = executor or get_global_executor()
    executor.add_node(node)
    try:
        executor.spin_once(timeout_sec)
    finally:
        executor.remove_node(node)


def spin_until_future_complete(node: Node, future: Any, executor: Executor | None = None,
                               timeout_sec: float | None = None) -> None:
    executor = executor or get_global_executor()
    executor.add_node(node)
    try:
        executor.spin_until_future_complete(future, timeout_sec)
    finally:
        executor.remove_node(node)


__all__ = ['Context', 'Node', 'create_node', 'get_default_context', 'get_global_executor', 'init',
           'ok', 'shutdown', 'spin', 'spin_once', 'spin_until_future_complete', 'try_shutdown']
