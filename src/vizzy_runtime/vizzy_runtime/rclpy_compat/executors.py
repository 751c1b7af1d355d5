"""rclpy.executors subset. Callbacks run in the spinning thread, which waits on a Cyclone waitset:
a subscription's reader holding samples, or Context.notify() (a service request, a timer reset, a
/clock tick that makes a timer due, shutdown), wakes it."""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Callable
from typing import Any

from .. import dds
from .context import Context, get_default_context
from .exceptions import ExternalShutdownException
from .node import Node

# Cap on a wait when a timer follows a sim-time clock that does not wake the executor when it
# moves (a node's own clock does: Node._on_clock_moved), since its deadline is not wall time.
_SIM_TIME_POLL_S = 0.005
# How often nodes look for peers using their topics with another message type.
_TYPE_CHECK_PERIOD_S = 2.0
# Longest wait inside Cyclone in the main thread: Python runs a signal's handler (SIGINT,
# SIGTERM: shutdown) only once the wait returns to the interpreter.
_SIGNAL_CHECK_S = 0.1
# Samples a subscription hands its callback per executor pass (then the others get their turn).
_TAKE_LIMIT = 256


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
        self._waitset: dds.WaitSet | None = None
        self._waitset_failed = False
        self._watched: dict[int, Any] = {}      # waitset key -> Subscription
        self._watched_version: tuple[int, int] | None = None
        self._nodes_version = 0
        # the context's generation when the last _run_ready began, and whether it left samples
        # behind: spin_once runs what is ready before waiting only when either says it may find
        # something (after a wake-up the previous spin_once ran everything already)
        self._ran_generation = -1
        self._left_samples = False

    def add_node(self, node: Node) -> bool:
        with self._lock:
            if node in self._nodes:
                return False
            self._nodes.append(node)
            self._nodes_version += 1
        self.context.notify()
        return True

    def remove_node(self, node: Node) -> None:
        with self._lock:
            if node in self._nodes:
                self._nodes.remove(node)
                self._nodes_version += 1

    def get_nodes(self) -> list[Node]:
        with self._lock:
            return list(self._nodes)

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        self._shutdown = True
        self.context.notify()
        return True

    def _run_ready(self) -> bool:
        did = False
        self._ran_generation, self._left_samples = self.context.generation, False
        if _time.monotonic() >= self._next_type_check:
            self._next_type_check = _time.monotonic() + _TYPE_CHECK_PERIOD_S
            for node in self.get_nodes():
                try:
                    node.check_topic_types()
                except Exception as err:  # noqa: BLE001 - a diagnostic must never stop a node
                    node.get_logger().debug(f'topic type check skipped: {err}')
        for node in self.get_nodes():
            for sub in list(node.subscriptions):
                taken = sub.take_and_dispatch(_TAKE_LIMIT)
                did |= taken > 0
                self._left_samples |= taken >= _TAKE_LIMIT
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

    def _watch(self) -> dds.WaitSet | None:
        """The waitset, watching the (non-direct) subscriptions of this executor's nodes; None
        where DDS cannot make one (the process is exiting)."""
        waitset = self._waitset
        if waitset is None:
            if self._waitset_failed:
                return None
            try:
                waitset = dds.WaitSet()
            except Exception:  # noqa: BLE001 - DdsClosedError or a DDS failure: wait as before
                self._waitset_failed = True
                return None
            self._waitset = waitset
            self.context._add_waker(waitset)
        version = (self.context.subscriptions_version, self._nodes_version)
        if version != self._watched_version:
            self._watched_version = version
            subs = {sub._wait_key: sub for node in self.get_nodes()
                    for sub in list(node.subscriptions) if not sub.direct}
            for key in set(self._watched) - set(subs):
                waitset.unwatch(key)
                del self._watched[key]
            for key, sub in subs.items():
                if key not in self._watched:
                    try:
                        waitset.watch(key, sub._reader)
                    except Exception as err:  # noqa: BLE001 - its reader is gone already
                        sub._node.get_logger().debug(f'{sub.topic}: not watched: {err}')
                        continue
                    self._watched[key] = sub
        return waitset

    def _wait(self, generation: int, timeout: float | None) -> None:
        """Wait up to timeout [s] (None: for ever) unless something happened since generation,
        and flag the subscriptions whose readers hold samples."""
        waitset = self._watch()
        quiet = (self.context.generation == generation and self.context.ok()
                 and not self._shutdown)
        if waitset is None:
            with self.context.wake:
                if quiet and self.context.generation == generation:
                    self.context.wake.wait(timeout)
            return
        if not quiet:
            timeout = 0.0
        elif threading.current_thread() is threading.main_thread():
            timeout = _SIGNAL_CHECK_S if timeout is None else min(timeout, _SIGNAL_CHECK_S)
        try:
            keys = waitset.wait(timeout)
        except Exception:  # noqa: BLE001 - DDS deleted at exit: the executor stops anyway
            self._waitset_failed, self._waitset = True, None
            return
        for key in keys:
            sub = self._watched.get(key)
            if sub is not None:
                sub._ready = True

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Run what is ready; if nothing is, wait up to timeout_sec (None: forever) for work and
        run it. As rclpy's, it returns early only for work, not for the executor's own wake-ups:
        a wait cut short by the main thread's signal check, the topic type check or a guard set
        before this call (rclpy.spin_once's own add_node) waits on; a notify() during the call
        (a shutdown, a node added) ends it."""
        if not self.context.ok():
            raise ExternalShutdownException()
        generation = self.context.generation
        # (a timer due or a reader with samples: the wait below returns at once, then they run)
        if (generation != self._ran_generation or self._left_samples) and self._run_ready():
            return
        deadline = None if timeout_sec is None else _time.monotonic() + timeout_sec
        while True:
            remaining = None if deadline is None else max(0.0, deadline - _time.monotonic())
            self._wait(generation, self._wait_timeout(remaining))
            if not self.context.ok():
                raise ExternalShutdownException()
            if (self._run_ready() or self._shutdown or self.context.generation != generation
                    or (deadline is not None and _time.monotonic() >= deadline)):
                return

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
