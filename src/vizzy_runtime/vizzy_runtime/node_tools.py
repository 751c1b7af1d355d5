"""What every Vizzy node repeats: its parameter table, callbacks that survive bad input, main().

Works on real rclpy and on the bundled runtime alike: like the nodes, it imports only from
vizzy_runtime.ros.

A node module writes:

    PARAMETERS = (('rate_hz', 15.0, 'Rate of ... [Hz], in (0, 120].'), ...)

    def check_parameter(name, value):   # why value is not acceptable, or None
        ...

    class MyNode(Node):
        def __init__(self):
            super().__init__('my_node')
            self._p = declare_parameters(self, PARAMETERS, check_parameter)
            self.create_subscription(Image, TOPIC,
                                     guarded(self, f'{TOPIC}: failed on an image', self._on_image),
                                     qos_profile_sensor_data)

    main = main_for(MyNode)
"""

from __future__ import annotations

import functools
import math
import threading
import time
from typing import Any, Callable, Collection, Iterable, Sequence

from vizzy_runtime.ros import (
    ExternalShutdownException, ParameterDescriptor, SetParametersResult, rclpy)

# (name, default, description) for each parameter a node declares.
ParameterTable = Sequence[tuple[str, Any, str]]
# check(name, value): why value is not acceptable for parameter name, or None if it is.
Check = Callable[[str, Any], 'str | None']
# check_all(values): what is wrong with the parameters taken together (None, one line or several).
CheckAll = Callable[[dict[str, Any]], 'str | Iterable[str] | None']


def _problems(found: str | Iterable[str] | None) -> list[str]:
    if not found:
        return []
    return [found] if isinstance(found, str) else [p for p in found if p]


def declare_parameters(node: Any, parameters: ParameterTable, check: Check, *,
                       read_only: Collection[str] = (), check_all: CheckAll | None = None,
                       on_change: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Declare the node's parameter table and keep it valid; returns {name: current value}.

    Each (name, default, description) is declared with a ParameterDescriptor carrying the
    description (and read_only for the names in read_only). Startup values (defaults, YAML,
    -p overrides) are checked with check(name, value) and check_all(values): any problem raises
    ValueError naming the node and every problem. Then an on-set-parameters callback refuses
    values that check or check_all reject, and changes to read_only names, with the reason in
    the SetParametersResult; when it accepts, it updates the returned dict in place and calls
    on_change({name: new value}) with the declared parameters whose value changed (to restart a
    timer, say).

    rclpy and the bundled runtime call the most recently added on-set callback first, so a node
    adds any further refusing callback after this one: a later refusal must not find the dict
    already updated.
    """
    read_only = frozenset(read_only)
    for name, default, description in parameters:
        node.declare_parameter(name, default, ParameterDescriptor(
            description=description, read_only=name in read_only))
    values = {name: node.get_parameter(name).value for name, _, _ in parameters}
    problems = [p for p in (check(n, v) for n, v in values.items()) if p]
    if check_all is not None:
        problems += _problems(check_all(dict(values)))
    if problems:
        raise ValueError(f'{node.get_name()}: bad parameters: ' + '; '.join(problems))

    def refuse(reason: str) -> Any:
        return SetParametersResult(successful=False, reason=reason)

    def on_set_parameters(params: list[Any]) -> Any:
        new = dict(values)
        for param in params:
            if param.name in read_only:
                return refuse(f'{param.name} is read-only; restart the node')
            try:
                problem = check(param.name, param.value)
            except Exception as exc:  # a value of a shape check did not expect
                problem = f'{param.name}: {type(exc).__name__}: {exc}'
            if problem:
                return refuse(problem)
            if param.name in new:
                new[param.name] = param.value
        if check_all is not None:
            problems = _problems(check_all(dict(new)))
            if problems:
                return refuse('; '.join(problems))
        changed = {n: v for n, v in new.items() if not _same(v, values[n])}
        values.update(new)
        if on_change is not None and changed:
            on_change(changed)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set_parameters)
    return values


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except Exception:  # e.g. numpy arrays: ambiguous truth value
        return False


def guarded(node: Any, what: str, callback: Callable[..., Any] | None = None, *,
            throttle_s: float = 5.0) -> Any:
    """callback wrapped so that an exception it raises is logged and swallowed, not raised.

    One bad message must never end the node: under real rclpy an exception escaping a callback
    ends spin. The error is logged as `<what>: <ExcType>: <message>`, at most once every
    throttle_s seconds for this wrapper (each guarded callback throttles on its own).
    Without callback, returns a decorator: guarded(node, what)(callback).
    """
    def wrap(fn: Callable[..., Any]) -> Callable[..., Any]:
        last = [-math.inf]  # time.monotonic() of the last error logged

        @functools.wraps(fn)
        def run_guarded(*args: Any, **kwargs: Any) -> Any:
            try:
                return fn(*args, **kwargs)
            except ExternalShutdownException:
                raise
            except Exception as exc:  # one bad message never kills the node
                now = time.monotonic()
                if now - last[0] >= throttle_s:
                    last[0] = now
                    node.get_logger().error(f'{what}: {type(exc).__name__}: {exc}')
                return None
        return run_guarded

    return wrap if callback is None else wrap(callback)


def replace_timer(node: Any, timer: Any, period_s: float, callback: Callable[[], Any]) -> Any:
    """Cancel and destroy timer; returns a new one calling callback every period_s seconds."""
    timer.cancel()
    node.destroy_timer(timer)
    return node.create_timer(period_s, callback)


class LatestWorker:
    """A thread that runs handle(item) on the newest item put(), one at a time, so that slow work
    (a CNN, a point cloud) never blocks the executor: an item the thread has not taken yet is
    replaced by a newer one (newest wins). min_period_s() (read before each start) spaces the
    starts. handle must not raise: wrap it with guarded() or catch inside. close() stops it."""

    def __init__(self, name: str, handle: Callable[[Any], Any],
                 min_period_s: Callable[[], float] = lambda: 0.0) -> None:
        self._handle = handle
        self._min_period_s = min_period_s
        self._wake = threading.Condition()
        self._item: Any = None
        self._waiting = False             # an item is there (it may be None)
        self._stop = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def put(self, item: Any) -> bool:
        """Hand item over; True if it replaced one that was still waiting (a dropped item)."""
        with self._wake:
            replaced = self._waiting
            self._item, self._waiting = item, True
            self._wake.notify()
        return replaced

    def _run(self) -> None:
        last = -math.inf
        while True:
            with self._wake:
                while not (self._waiting or self._stop):
                    self._wake.wait()
                while not self._stop:       # the rate: a put() meanwhile replaces the item
                    wait = last + self._min_period_s() - time.monotonic()
                    if wait <= 0.0:
                        break
                    self._wake.wait(wait)
                if self._stop:
                    return
                item, self._item, self._waiting = self._item, None, False
            last = time.monotonic()
            self._handle(item)

    def close(self, timeout: float = 30.0) -> None:
        """Stop taking items; wait up to timeout for the one in hand (not from its own thread)."""
        with self._wake:
            self._stop = True
            self._wake.notify_all()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout)


def run(node_factory: Callable[[], Any], args: list[str] | None = None) -> None:
    """The standard main: init, spin node_factory() until Ctrl-C or shutdown, clean up."""
    rclpy.init(args=args)
    try:
        node = node_factory()
        try:
            rclpy.spin(node)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown()


def main_for(node_factory: Callable[[], Any]) -> Callable[..., None]:
    """A console-script main(args=None) that runs node_factory (see run)."""
    def main(args: list[str] | None = None) -> None:
        run(node_factory, args)

    name = getattr(node_factory, '__name__', 'the node')
    main.__doc__ = f'Run {name} until Ctrl-C (or SIGTERM, or shutdown).'
    return main


__all__ = ['Check', 'CheckAll', 'LatestWorker', 'ParameterTable', 'declare_parameters', 'guarded',
           'main_for', 'replace_timer', 'run']
