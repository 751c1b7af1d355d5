"""rclpy.executors subset. Callbacks run in the spinning thread; Cyclone listeners only wake it."""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Callable
from typing import Any

from .context import Context, get_default_context
from .exceptions import ExternalShutdownException
from .node import Node

# Cap on a wait when a timer follows a sim-time clock that does not wake the executor when it
# moves (a node's own clock does: Node._on_clock_moved), since its deadline is not wall time.
_SIM_TIME_POLL_S = 0.005
# How often nodes look for peers using their topics with another message type.
_TYPE_CHECK_PERIOD_S = 2.0


class Future:
    """rclpy.task.Future subset, for spin_until_future_complete. executor: rclpy wakes it when
    the future is done; here whoever completes a future already wakes the executor."""

    def __init__(self, *, executor: Executor | None = None) -> None:
        self._done = False
        self._result: Any = None
        self._exception: BaseException | None = None
        self._callbacks: list[Callable[[Future], None]] = []

    def done(self) -> bool:
        return self._done

    def result(self) -> Any:
        if self._exception:
            raise self._exception
        return self._result

    def set_result(self, result: Any) -> None:
        self._result, self._done = result, True
        for cb in self._callbacks:
            cb(self)

    def set_exception(self, exception: BaseException) -> None:
        self._exception, self._done = exception, True

    def add_done_callback(self, callback: Callable[[Future], None]) -> None:
        self._callbacks.append(callback)


class Executor:
    def __init__(self, *, context: Context | None = None) -> None:
        self.context = context or get_default_context()
        self._nodes: list[Node] = []
        self._lock = threading.Lock()
        self._shutdown = False
        self._next_type_check = _time.monotonic() + 0.5

    def add_node(self, node: Node) -> bool:
        with self._lock:
            if node in self._nodes:
                return False
            self._nodes.append(node)
        self.context.notify()
        return True

    def remove_node(self, node: Node) -> None:
        with self._lock:
            if node in self._nodes:
                self._nodes.remove(node)

    def get_nodes(self) -> list[Node]:
        with self._lock:
            return list(self._nodes)

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        self._shutdown = True
        self.context.notify()
        return True

    def _run_ready(self) -> bool:
        did = False
        if _time.monotonic() >= self._next_type_check:
            self._next_type_check = _time.monotonic() + _TYPE_CHECK_PERIOD_S
            for node in self.get_nodes():
                try:
                    node.check_topic_types()
                except Exception as err:  # noqa: BLE001 - a diagnostic must never stop a node
                    node.get_logger().debug(f'topic type check skipped: {err}')
        for node in self.get_nodes():
            for sub in list(node.subscriptions):
                did |= sub.take_and_dispatch() > 0
            for srv in list(node.services) + list(node.clients):
                if srv.ready:
                    srv.serve()
                    did = True
            for timer in list(node.timers):
                if timer.is_ready():
                    timer.call()
                    did = True
        return did

    def _wait_timeout(self, limit: float | None) -> float | None:
        best = max(0.0, self._next_type_check - _time.monotonic())
        best = best if limit is None else min(best, limit)
        for node in self.get_nodes():
            for timer in node.timers:
                if timer.is_canceled():
                    continue
                wait = max(0.0, timer.time_until_next_call() / 1e9)
                if timer.clock.ros_time_is_active:
                    if wait > 0.0 and getattr(timer.clock, 'wakes_executor', False):
                        continue        # only /clock moves it, and that wakes this executor
                    wait = min(wait, _SIM_TIME_POLL_S)
                best = wait if best is None else min(best, wait)
        return best

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Run what is ready; if nothing is, wait up to timeout_sec (None: forever) and run that."""
        if not self.context.ok():
            raise ExternalShutdownException()
        generation = self.context.generation
        if self._run_ready():
            return
        timeout = self._wait_timeout(timeout_sec)
        with self.context.wake:
            if self.context.generation == generation and self.context.ok() and not self._shutdown:
                self.context.wake.wait(timeout)
        if not self.context.ok():
            raise ExternalShutdownException()
        self._run_ready()

    def spin(self) -> None:
        while self.context.ok() and not self._shutdown:
            self.spin_once()

    def spin_until_future_complete(self, future: Future, timeout_sec: float | None = None) -> None:
        deadline = None if timeout_sec is None else _time.monotonic() + timeout_sec
        while self.context.ok() and not future.done():
            remaining = None if deadline is None else deadline - _time.monotonic()
            if remaining is not None and remaining <= 0:
                return
            self.spin_once(remaining if remaining is None else min(remaining, 0.1))


class SingleThreadedExecutor(Executor):
    pass


class MultiThreadedExecutor(Executor):
    """Runs callbacks in the spinning thread, like SingleThreadedExecutor: our nodes need no
    more."""

    def __init__(self, num_threads: int | None = None, *, context: Context | None = None) -> None:
        super().__init__(context=context)
