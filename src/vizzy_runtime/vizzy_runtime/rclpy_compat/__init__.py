"""The bundled rclpy: the subset of rclpy's API our nodes use, on Cyclone DDS (see
vizzy_runtime.ros)."""

from __future__ import annotations

import signal
import threading
from typing import Any

from .context import Context, get_default_context
from .executors import Executor, SingleThreadedExecutor
from .node import Node

_global_executor: Executor | None = None
# The handler init() found for each signal it took over (rclpy's handler chains to it too).
_previous_handlers: dict[int, Any] = {}


def _on_signal(signum: int, frame: Any) -> None:
    """SIGINT/SIGTERM, like rclpy's handler: shut the context down (ok() turns False and
    publishing fails, as with rcl) so spin returns between callbacks, then call the handler that
    was installed before init() if it was a Python function, as rclpy chains to it.

    Where that was Python's default (or nothing), this runtime deliberately raises no
    KeyboardInterrupt for the first signal, where rclpy's chaining to Python's default handler
    does: raised at an arbitrary point (inside a callback, a C call or the clean-up itself) it
    could kill the process without its clean-up. A further signal once the context is down
    raises KeyboardInterrupt, for a node that hangs."""
    context = get_default_context()
    was_ok = context.ok()
    if was_ok:
        context.request_shutdown()
    previous = _previous_handlers.get(signum)
    if callable(previous) and previous is not signal.default_int_handler:
        previous(signum, frame)
    elif not was_ok:
        raise KeyboardInterrupt


def init(*, args: list[str] | None = None, context: Context | None = None,
         domain_id: int | None = None, signal_handler_options: int | None = None) -> None:
    """rclpy.init: parse --ros-args (from sys.argv when args is None); SIGINT and SIGTERM shut
    the context down and end spin (see _on_signal), whatever handler was there before (even
    SIG_IGN), as rclpy's. signal_handler_options: rclpy's SignalHandlerOptions as an int (0 none,
    1 SIGINT, 2 SIGTERM, 3 both); by default both for the default context, none otherwise."""
    import sys
    (context or get_default_context()).init(sys.argv if args is None else args,
                                            domain_id=domain_id)
    if signal_handler_options is None:
        signal_handler_options = 3 if context in (None, get_default_context()) else 0
    if threading.current_thread() is threading.main_thread():
        for bit, sig in ((1, signal.SIGINT), (2, signal.SIGTERM)):
            if not int(signal_handler_options) & bit:
                continue
            current = signal.getsignal(sig)
            if current is not _on_signal:
                _previous_handlers[sig] = current
                signal.signal(sig, _on_signal)


def ok(*, context: Context | None = None) -> bool:
    return (context or get_default_context()).ok()


def shutdown(*, context: Context | None = None, uninstall_handlers: bool | None = None) -> None:
    (context or get_default_context()).shutdown()


def try_shutdown(*, context: Context | None = None) -> None:
    (context or get_default_context()).try_shutdown()


def create_node(node_name: str, *, context: Context | None = None,
                cli_args: list[str] | None = None, namespace: str | None = None,
                use_global_arguments: bool = True, enable_rosout: bool = True,
                start_parameter_services: bool = True, parameter_overrides: list[Any] | None = None,
                allow_undeclared_parameters: bool = False,
                automatically_declare_parameters_from_overrides: bool = False,
                enable_logger_service: bool = False) -> Node:
    """rclpy.create_node: Node(node_name, ...) with the same keywords."""
    return Node(node_name, context=context, cli_args=cli_args, namespace=namespace,
                use_global_arguments=use_global_arguments, enable_rosout=enable_rosout,
                start_parameter_services=start_parameter_services,
                parameter_overrides=parameter_overrides,
                allow_undeclared_parameters=allow_undeclared_parameters,
                automatically_declare_parameters_from_overrides=(
                    automatically_declare_parameters_from_overrides),
                enable_logger_service=enable_logger_service)


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


def spin_once(node: Node, *, executor: Executor | None = None,
              timeout_sec: float | None = None) -> None:
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
