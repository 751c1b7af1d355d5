"""rclpy.context.Context: init/shutdown state, global --ros-args, and the wake-up condition
executors wait on."""

from __future__ import annotations

import os
import threading
import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from . import arguments

if TYPE_CHECKING:
    from .node import Node


class Context:
    def __init__(self) -> None:
        self._ok = False
        self._stop_requested = False  # set by SIGINT/SIGTERM: executors leave spin at a safe point
        self._lock = threading.RLock()
        self.wake = threading.Condition(self._lock)
        self.args = arguments.RosArguments()
        self.nodes: list[Node] = []
        self._on_shutdown: list[Callable[[], None]] = []
        self._discovery: Any = None
        self.generation = 0  # bumped whenever something is ready to run
        self.subscriptions_version = 0  # bumped when a node makes or destroys a subscription
        self._wakers: weakref.WeakSet[Any] = weakref.WeakSet()  # executors' waitsets

    def init(self, args: list[str] | None = None, *, initialize_logging: bool = True,
             domain_id: int | None = None) -> None:
        """rclpy's Context.init. initialize_logging: this runtime's logging needs no set-up, so
        it changes nothing either way."""
        with self._lock:
            if self._ok:
                raise RuntimeError('Context.init() must only be called once')
            if domain_id is not None:
                os.environ['ROS_DOMAIN_ID'] = str(domain_id)
            self.args = arguments.parse(args)
            if self.args.log_level:
                from .logging import set_default_level
                set_default_level(self.args.log_level)
            self._ok = True
            self._stop_requested = False

    def ok(self) -> bool:
        return self._ok and not self._stop_requested

    def request_shutdown(self) -> None:
        """What the signal handler does: ok() turns False and spinning stops between callbacks
        (never in the middle of one); the node's main then cleans up with try_shutdown()."""
        self._stop_requested = True
        self.notify()

    def notify(self) -> None:
        with self.wake:
            self.generation += 1
            self.wake.notify_all()
            for waitset in self._wakers:     # executors waiting on DDS (executors.py)
                waitset.wake()

    def _add_waker(self, waitset: Any) -> None:
        """An executor's waitset (dds.WaitSet): notify() wakes it too (kept while it lives)."""
        with self.wake:
            self._wakers.add(waitset)

    def _subscriptions_changed(self) -> None:
        """A subscription was made or destroyed: executors update what they wait on."""
        with self.wake:
            self.subscriptions_version += 1
        self.notify()

    def on_shutdown(self, callback: Callable[[], None]) -> None:
        self._on_shutdown.append(callback)

    def shutdown(self) -> None:
        with self._lock:
            if not self._ok:
                raise RuntimeError('Context must be initialized before it can be shutdown')
            self._ok = False
            callbacks, self._on_shutdown = self._on_shutdown, []
        for node in list(self.nodes):
            try:
                node.destroy_node()
            except Exception as err:  # noqa: BLE001 - e.g. a node whose __init__ failed half-way
                # (rclpy itself destroys no node at shutdown): free what the base class made
                from .node import Node
                node.get_logger().debug(f'destroy_node at shutdown: {type(err).__name__}: {err}')
                Node.destroy_node(node)
        for cb in callbacks:
            cb()
        self.notify()

    def try_shutdown(self) -> None:
        if self._ok:
            self.shutdown()

    def discovery(self) -> Any:
        """DDS builtin-topic view of the graph, created on first use (topic lists, counts)."""
        with self._lock:
            if self._discovery is None:
                from .. import dds
                self._discovery = dds.Discovery()
            return self._discovery


_default_context = Context()


def get_default_context(*, shutting_down: bool = False) -> Context:
    """rclpy's: shutting_down=True asks for no new context to be made; this runtime has one
    default context for the process and never replaces it, so both return the same."""
    return _default_context
