"""What every Vizzy node repeats: its parameter table, callbacks that survive bad input, main().

Works on real rclpy and on the bundled runtime alike: like the nodes, it imports only from
vizzy_runtime.ros.

A node module writes:

    PARAMETERS = (
        Param('rate_hz', 15.0, 'Rate of ... [Hz], in (0, 120].', '(0, 120]'),
        Param('mode', 'fast', 'fast or exact.', choices=('fast', 'exact')),
        ...)

    def check_parameter(name, value):   # why value is not acceptable (beyond the table's
        ...                             # ranges and choices), or None

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

import faulthandler
import functools
import gc
import math
import os
import re
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from vizzy_runtime.loopback import exec_loopback_bound
from vizzy_runtime.process_exit import run_then_exit
from vizzy_runtime.ros import (
    ExternalShutdownException,
    FloatingPointRange,
    IntegerRange,
    InvalidHandle,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    Node,
    ParameterDescriptor,
    ParameterException,
    RCLError,
    SetParametersResult,
    rclpy,
)

INT64_MIN, INT64_MAX = -2 ** 63, 2 ** 63 - 1
_INTERVAL = re.compile(r'^\s*([\[(])\s*([^,\s]+)\s*,\s*([^,\s]+)\s*([\])])\s*$')


def _number(text: str) -> int | float:
    try:
        return int(text)
    except ValueError:
        return float(text)  # 0.25, 1e5, inf, -inf


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _bound_text(bound: int | float) -> str:
    """1e5 -> '100000', 0.25 -> '0.25'; a float that :g would round keeps all its digits."""
    if isinstance(bound, int):
        return str(bound)
    short = f'{bound:g}'
    return short if float(short) == bound else repr(bound)


@dataclass(frozen=True)
class Param:
    """One row of a node's parameter table, declared with the ParameterDescriptor it describes.

    range: the accepted interval in the usual notation, '[1, 10]', '(0, 120]', '[0, inf)'. The
    descriptor carries it as an IntegerRange (integer default) or a FloatingPointRange (double
    default), step 0 unless step is given, so the middleware itself refuses values outside, on
    either runtime. ROS ranges are inclusive (and admit a double within 1e-6 relative of a
    bound): an excluded integer bound becomes the next integer, exactly; an excluded double bound
    stays in the descriptor's range, additional_constraints says 'in (0, 120]', and
    declare_parameters' on-set callback refuses the bound itself. 'inf' is no bound (for an
    integer, the int64 limit); a double range with inf admits inf unless the bound is excluded.
    choices: the only accepted values (refused otherwise by the on-set callback).
    read_only: the descriptor's read_only (set at start-up only; the middleware refuses changes).
    constraints: additional_constraints text for the rules that check / check_all enforce (list
    shapes, cross-parameter rules, files), so `ros2 param describe` shows every rule.
    """

    name: str
    default: Any
    description: str
    range: str | None = None
    step: int | float = 0
    choices: tuple[Any, ...] = ()
    read_only: bool = False
    constraints: str = ''

    def __post_init__(self) -> None:
        if self.range is not None:
            if not _is_number(self.default):
                raise TypeError(f'{self.name}: a range needs a number default, '
                                f'not {self.default!r}')
            lo, hi = self.descriptor_bounds()  # a malformed range fails at import
            if not lo <= self.default <= hi:
                raise ValueError(f'{self.name}: default {self.default!r} outside {self.range}')
        problem = self.refusal(self.default)
        if problem:
            raise ValueError(f'default: {problem}')

    def bounds(self) -> tuple[int | float, int | float, bool, bool]:
        """(low, high, low excluded, high excluded) of range."""
        match = _INTERVAL.match(self.range or '')
        if not match:
            raise ValueError(f"{self.name}: range {self.range!r} is not like '[0, 1]' or "
                             "'(0, inf)'")
        opening, low, high, closing = match.groups()
        try:
            lo, hi = _number(low), _number(high)
        except ValueError:
            raise ValueError(f'{self.name}: range {self.range!r} has a bound that is no '
                             'number') from None
        if not lo < hi:
            raise ValueError(f'{self.name}: range {self.range!r} is empty')
        return lo, hi, opening == '(', closing == ')'

    def descriptor_bounds(self) -> tuple[int | float, int | float]:
        """The descriptor range's inclusive (from_value, to_value)."""
        lo, hi, lo_open, hi_open = self.bounds()
        if not isinstance(self.default, int):
            return float(lo), float(hi)
        for bound in (lo, hi):
            if not (isinstance(bound, int) or math.isinf(bound)):
                raise ValueError(f'{self.name}: integer range {self.range!r} has a '
                                 'fractional bound')
        lo = INT64_MIN if lo == -math.inf else int(lo) + lo_open
        hi = INT64_MAX if hi == math.inf else int(hi) - hi_open
        return lo, hi

    def additional_constraints(self) -> str:
        """The descriptor's additional_constraints: what its range cannot say."""
        parts = []
        if self.range is not None and isinstance(self.default, float):
            lo, hi, lo_open, hi_open = self.bounds()
            if lo_open or hi_open:
                parts.append(f'in {self.interval()}')
        if self.choices:
            parts.append('one of: ' + ', '.join(str(c) for c in self.choices))
        if self.constraints:
            parts.append(self.constraints)
        return '; '.join(parts)

    def interval(self) -> str:
        lo, hi, lo_open, hi_open = self.bounds()
        return (f'{"(" if lo_open else "["}{_bound_text(lo)}, {_bound_text(hi)}'
                f'{")" if hi_open else "]"}')

    def descriptor(self) -> Any:
        """The ParameterDescriptor to declare the parameter with (a new one each time)."""
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only,
                                         additional_constraints=self.additional_constraints())
        if self.range is not None:
            lo, hi = self.descriptor_bounds()
            if isinstance(self.default, int):
                descriptor.integer_range = [IntegerRange(from_value=lo, to_value=hi,
                                                         step=int(self.step))]
            else:
                descriptor.floating_point_range = [FloatingPointRange(
                    from_value=lo, to_value=hi, step=float(self.step))]
        return descriptor

    def range_rule(self) -> str:
        return f'out of range {self.interval()}' + (f' (step {self.step:g})' if self.step else '')

    def refusal(self, value: Any) -> str | None:
        """Why value breaks a rule the descriptor cannot enforce (an excluded double bound, the
        choices), or None."""
        if self.choices and value not in self.choices:
            choices = ', '.join(str(c) for c in self.choices)
            return f'{self.name} must be one of: {choices}; got {value!r}'
        if self.range is not None and isinstance(self.default, float) and _is_number(value):
            lo, hi, lo_open, hi_open = self.bounds()
            if (lo_open and value <= lo) or (hi_open and value >= hi):
                return f"{self.name} must be in {self.interval()}, got {value!r}"
        return None

    @classmethod
    def of(cls, row: Param | tuple[str, Any, str]) -> Param:
        """A table row as a Param (a bare (name, default, description) tuple has no rules)."""
        return row if isinstance(row, Param) else cls(*row)


# A node's parameter table: Param rows (or bare (name, default, description) tuples).
ParameterTable = Sequence['Param | tuple[str, Any, str]']
# check(name, value): why value is not acceptable for parameter name, or None if it is.
Check = Callable[[str, Any], 'str | None']
# check_all(values): what is wrong with the parameters taken together (None, one line or several).
CheckAll = Callable[[dict[str, Any]], 'str | Iterable[str] | None']


class ParameterError(ValueError):
    """Parameters a node cannot start with. str(): one line, '<node>: <problem>; <problem>',
    each problem naming its parameter and the rule ("parameter 'levels' = -3: out of range
    [1, 10]")."""

    def __init__(self, node_name: str, problems: Sequence[str]) -> None:
        self.node_name = node_name
        self.problems = [_one_line(p) for p in problems]
        super().__init__(f'{node_name}: ' + '; '.join(self.problems))


def _one_line(text: str) -> str:
    return ' '.join(str(text).split())


def _problems(found: str | Iterable[str] | None) -> list[str]:
    if not found:
        return []
    return [found] if isinstance(found, str) else [p for p in found if p]


def _checked(check: Check | None, name: str, value: Any) -> str | None:
    if check is None:
        return None
    try:
        return check(name, value)
    except Exception as exc:  # a value of a shape check did not expect
        return f'{name}: {type(exc).__name__}: {exc}'


# rclpy's (Jazzy) exception texts; the bundled runtime raises the same ones.
_TYPE_TEXT = re.compile(r"^Trying to set parameter '(?P<name>.*)' to '(?P<value>.*)' of type "
                        r"'(?P<got>\w+)', expecting type '(?:Type\.)?(?P<want>\w+)'")
_VALUE_TEXT = re.compile(r'^Invalid parameter value \((?P<value>.*?)\) for parameter\. '
                         r'Reason: (?P<reason>.*): (?P<name>[^:]*)$', re.DOTALL)
_RANGE_REASON = re.compile(r'^(Parameter \S+ out of range|The parameter value for \S+ is not)')


def _refusal_of(exc: BaseException, spec: Param | None = None) -> tuple[str, str, str] | None:
    """(name, value as text, rule) from rclpy's InvalidParameterTypeException /
    InvalidParameterValueException text, or None. With spec, a range refusal reads as the spec's
    interval rather than rclpy's 'Min: .., Max: ..'."""
    text = str(exc)
    found = _TYPE_TEXT.match(text)
    if found:
        value = found['value']
        value = repr(value) if found['got'] == 'STRING' else value
        return (found['name'], value,
                f'expected {found["want"].lower()}, got {found["got"].lower()}')
    found = _VALUE_TEXT.match(text)
    if found:
        reason = found['reason']
        if spec is not None and spec.range is not None and _RANGE_REASON.match(reason):
            reason = spec.range_rule()
        return found['name'], found['value'], _one_line(reason)
    return None


def _problem_text(name: str, value: str, rule: str) -> str:
    return f"parameter '{name}' = {value}: {rule}"


def declare_parameters(node: Any, parameters: ParameterTable, check: Check | None = None, *,
                       check_all: CheckAll | None = None,
                       on_change: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Declare the node's parameter table and keep it valid; returns {name: current value}.

    Each row is declared with its Param.descriptor() (description, range, read_only,
    additional_constraints), so the middleware refuses a value of another type, outside the
    range or of a read-only parameter, on either runtime. Start-up values (defaults, YAML, -p
    overrides) must also pass the rules the descriptor cannot express (Param.refusal: excluded
    double bounds, choices), check(name, value) and check_all(values); any problem, a refused
    declaration included, raises ParameterError (a ValueError), one line naming the node and
    every problem. Then an on-set-parameters callback refuses values those rules reject, with the
    reason in the SetParametersResult; and a post-set-parameters callback (run only once every
    on-set callback accepted and the values are set) updates the returned dict in place and calls
    on_change({name: new value}) with the declared parameters whose value changed (to restart a
    timer, say). An exception on_change raises is logged, not raised: the values are set by then.
    """
    specs = [Param.of(row) for row in parameters]
    values: dict[str, Any] = {}
    problems: list[str] = []
    for spec in specs:      # every row is declared (or refused) before any check runs
        try:
            values[spec.name] = node.declare_parameter(spec.name, spec.default,
                                                       spec.descriptor()).value
        except (InvalidParameterTypeException, InvalidParameterValueException) as exc:
            refused = _refusal_of(exc, spec)
            problems.append(_problem_text(*refused) if refused else _one_line(str(exc)))
            values[spec.name] = spec.default  # not declared; check_all below still sees a value
    for spec in specs:
        if node.has_parameter(spec.name):
            value = values[spec.name]
            problem = spec.refusal(value) or _checked(check, spec.name, value)
            if problem:
                problems.append(_problem_text(spec.name, repr(value), problem))
    if check_all is not None:
        try:
            problems += _problems(check_all(dict(values)))
        except Exception as exc:  # values of a shape check_all did not expect
            problems.append(f'{type(exc).__name__}: {exc}')
    if problems:
        raise ParameterError(node.get_name(), problems)
    by_name = {spec.name: spec for spec in specs}

    def on_set_parameters(params: list[Any]) -> Any:
        new = dict(values)
        for param in params:
            spec = by_name.get(param.name)
            if spec is None:
                continue
            problem = spec.refusal(param.value) or _checked(check, param.name, param.value)
            if problem:
                return SetParametersResult(successful=False, reason=problem)
            new[param.name] = param.value
        if check_all is not None:
            try:
                found = _problems(check_all(new))
            except Exception as exc:
                found = [f'{type(exc).__name__}: {exc}']
            if found:
                return SetParametersResult(successful=False, reason='; '.join(found))
        return SetParametersResult(successful=True)

    def post_set_parameters(params: list[Any]) -> None:
        changed = {p.name: p.value for p in params
                   if p.name in values and not _same(p.value, values[p.name])}
        values.update(changed)
        if on_change is not None and changed:
            try:
                on_change(changed)
            except Exception as exc:  # the values are set: say what did not follow them
                node.get_logger().error(f'applying {", ".join(changed)} failed: '
                                        f'{type(exc).__name__}: {exc}')

    node.add_on_set_parameters_callback(on_set_parameters)
    node.add_post_set_parameters_callback(post_set_parameters)
    return values


def startup_error_line(exc: BaseException) -> str | None:
    """The one line to print, instead of a traceback, for a node that cannot start because of
    its parameters or --ros-args; None if exc is no such error.

    Handles ParameterError (declare_parameters), rclpy's parameter exceptions from any
    declare_parameter (the node is named when the traceback passes through it), the bundled
    runtime's RosArgumentError and rcl's "Couldn't parse ..." RCLError from rclpy.init (a bad
    params file or -p rule; no node exists yet).
    """
    if isinstance(exc, ParameterError):
        return str(exc)
    if isinstance(exc, ParameterException):
        refused = _refusal_of(exc)
        text = _problem_text(*refused) if refused else _one_line(str(exc))
        node_name = _node_in_traceback(exc)
        return f'{node_name}: {text}' if node_name else text
    if type(exc).__name__ == 'RosArgumentError':
        return _one_line(str(exc))
    if type(exc).__name__ == 'RCLError' and "Couldn't parse" in str(exc):
        # drop rcl's ', at /path/file.c:123' source locations
        return _one_line(re.sub(r', at \S+:\d+', '', str(exc)))
    return None


def _node_in_traceback(exc: BaseException) -> str | None:
    tb = exc.__traceback__
    while tb is not None:
        candidate = tb.tb_frame.f_locals.get('self')
        if isinstance(candidate, Node):
            try:
                return candidate.get_name()
            except Exception:  # a node too broken to say its name
                return None
        tb = tb.tb_next
    return None


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except Exception:  # e.g. numpy arrays: ambiguous truth value
        return False


def guarded(node: Any, what: str, callback: Callable[..., Any] | None = None, *,
            throttle_s: float = 5.0, topic: str | None = None) -> Any:
    """callback wrapped so that an exception it raises is logged and swallowed, not raised.

    One bad message must never end the node: under real rclpy an exception escaping a callback
    ends spin. The error is logged as `<what>: <ExcType>: <message>`, at most once every
    throttle_s seconds for this wrapper (each guarded callback throttles on its own).
    ExternalShutdownException passes through, and so does, as ExternalShutdownException, a
    failure that only says the node is going away (see publish_from_thread): Ctrl-C shuts the
    context down while a callback may be publishing. Without callback, returns a decorator:
    guarded(node, what)(callback). With topic, and a node that has an `input_health`
    (InputHealth), the exception is counted there as a refusal of that topic's input (reason:
    `<what>: <ExcType>`), which logs it (first time, then throttled) and reports it on
    /diagnostics.
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
                if _going_away(node, exc):
                    raise ExternalShutdownException() from None
                health = getattr(node, 'input_health', None) if topic is not None else None
                if health is not None:
                    health.refuse(topic, f'{what}: {type(exc).__name__}', str(exc))
                    return None
                now = time.monotonic()
                if now - last[0] >= throttle_s:
                    last[0] = now
                    where = f'{topic}: ' if topic is not None else ''
                    node.get_logger().error(f'{where}{what}: {type(exc).__name__}: {exc}')
                return None
        return run_guarded

    return wrap if callback is None else wrap(callback)


def replace_timer(node: Any, timer: Any, period_s: float, callback: Callable[[], Any]) -> Any:
    """Cancel and destroy timer; returns a new one calling callback every period_s seconds."""
    timer.cancel()
    node.destroy_timer(timer)
    return node.create_timer(period_s, callback)


def has_subscribers(publisher: Any) -> bool:
    """Whether anything reads publisher's topic now (a node, a bag recorder, a viewer): a node
    skips building what nobody reads, as image_transport's lazy publishers do (an overlay, an
    uncompressed copy). A publisher that cannot tell counts as read."""
    try:
        return int(publisher.get_subscription_count()) > 0
    except Exception:  # noqa: BLE001 - destroyed meanwhile: publish() will say so
        return True


def publish_from_thread(node: Any, publisher: Any, msg: Any) -> None:
    """publisher.publish(msg) from a thread of the node's own (a LatestWorker, a render loop),
    where the node may be going away meanwhile: then ExternalShutdownException, not an error.

    That is: the node's context is shut down (rclpy's signal handler does it on the first
    SIGINT/SIGTERM, before spin returns and before destroy_node() can stop the thread) and the
    publish fails with RCLError, or the publisher is destroyed (destroy_node() gave up waiting for
    the thread) and it fails with InvalidHandle. guarded() lets ExternalShutdownException through
    and LatestWorker ends its thread on it, quietly; the thread must log nothing more (rclpy
    would also fail to send that to /rosout). Any other failure is raised as it is.
    """
    if not node.context.ok():
        raise ExternalShutdownException()
    try:
        publisher.publish(msg)
    except (InvalidHandle, RCLError) as exc:
        if _going_away(node, exc):
            raise ExternalShutdownException() from None
        raise


def _going_away(node: Any, exc: BaseException) -> bool:
    """exc only says that node is being destroyed or its context shut down."""
    return isinstance(exc, InvalidHandle) or (isinstance(exc, RCLError) and not node.context.ok())


class LatestWorker:
    """A thread that runs handle(item) on the newest item put(), one at a time, so that slow work
    (a CNN, a point cloud) never blocks the executor: an item the thread has not taken yet is
    replaced by a newer one (newest wins). min_period_s() (read before each start) spaces the
    starts. handle must not raise: wrap it with guarded() or catch inside; ExternalShutdownException
    (see publish_from_thread) ends the thread quietly.

    close(), from the node's destroy_node() before the base class's: a thread waiting for an item
    or for its rate ends at once; a handle in flight cannot be interrupted, so close() waits for
    it at most timeout (CLOSE_TIMEOUT_S) and then leaves the daemon thread to finish on its own
    (the process ends it at exit): whatever it publishes after that is dropped by
    publish_from_thread. Our slowest handle, a cylinder detector cloud, takes up to about 1.4 s on
    a loaded 2-core machine; waiting 1 s at most keeps a node's stop within issue 12's 2 s of
    SIGINT (bench/lifecycle.py) and far inside the 5 s a launcher allows before SIGTERM."""

    CLOSE_TIMEOUT_S = 1.0

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
            try:
                self._handle(item)
            except ExternalShutdownException:   # the node is going away: end without a word
                with self._wake:
                    self._stop = True
                return

    def close(self, timeout: float | None = None) -> bool:
        """Stop taking items; wait up to timeout (default CLOSE_TIMEOUT_S) for the handle in
        flight, not from the worker's own thread. True if the thread has ended."""
        with self._wake:
            self._stop = True
            self._wake.notify_all()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(self.CLOSE_TIMEOUT_S if timeout is None else timeout)
        return not self._thread.is_alive()


_signals_received: list[int] = []
STACKS_SIGNAL = signal.SIGUSR1


def _on_termination_signal(signum: int, frame: Any) -> None:
    """run()'s SIGINT/SIGTERM handler, called by the runtime's own (which has already shut the
    context down): it only notes the signal. No KeyboardInterrupt, ever."""
    _signals_received.append(signum)


def _spin_through_faults(node: Any) -> None:
    """rclpy.spin(node), resumed after an exception raised by a callback that is not the node's
    own (those are guarded()): e.g. rclpy's TimeSource raises 'Seconds value must not be negative'
    on a /clock sample with a negative time, which would otherwise end the node. Each such fault is
    logged (the first, then every 100th) with its count; a stop (signal, shutdown) ends the spin."""
    faults = 0
    while True:
        try:
            rclpy.spin(node)
            return
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:
            if not rclpy.ok():
                raise
            faults += 1
            if faults % 100 == 1:
                node.get_logger().error(
                    f'fault {faults} outside the node\'s callbacks, the node keeps running: '
                    f'{type(exc).__name__}: {exc}')


def run(node_factory: Callable[[], Any], args: list[str] | None = None, *,
        cannot_start: tuple[type[BaseException], ...] = ()) -> None:
    """The standard main: init, spin node_factory() until Ctrl-C, SIGTERM or shutdown, clean up.

    A node that cannot start because of its parameters or --ros-args (see startup_error_line)
    ends with that one line on stderr and exit status 2, never a traceback. An exception of a
    cannot_start class from node_factory() (what the host lacks, e.g. the sim's renderer) ends it
    with '[<executable>] cannot start: <the exception>' and exit status 1.

    Signals: SIGINT and SIGTERM get a handler that raises nothing, installed before rclpy.init()
    so that the runtime's handler (rclpy's and the bundled one alike) chains to it instead of to
    Python's default, which raises KeyboardInterrupt wherever the main thread is: inside a
    callback, inside rclpy's C++ take (a RuntimeError then), or inside destroy_node() when the
    second SIGINT of `ros2 launch` plus a terminal's Ctrl-C arrives. The first signal shuts the
    context down and spin returns; clean-up then runs to the end with SIGINT ignored (SIG_IGN:
    Python resets function handlers while it exits) and SIGTERM at its default, so a launcher's
    escalation still ends a clean-up that hangs. A signal during start-up ends the node quietly.
    """
    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread:
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, _on_termination_signal)
        # SIGUSR1 prints every thread's stack (the launcher sends it to a node that has not
        # stopped within its grace, before SIGTERM: the log then says where it was stuck)
        faulthandler.register(STACKS_SIGNAL, all_threads=True)
    node = None
    try:
        rclpy.init(args=args)
        # The executor spin() uses, made now: built after a signal shut the context down (during
        # the node's seconds of start-up) rclpy's constructor fails half-way and its __del__
        # prints a traceback at exit.
        rclpy.get_global_executor()
        node = node_factory()
        # What start-up built (modules, models, caches) becomes permanent: the collector's full
        # passes never walk it again, nor does the final collection at exit (foveation stopped in
        # 1.25 s after SIGINT, 1.1 s of it that collection; 0.15 s with the freeze).
        gc.freeze()
        _spin_through_faults(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        if not ((_signals_received or node is not None) and not rclpy.ok()):
            if node is None and isinstance(exc, cannot_start):
                name = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else 'node'
                print(f'[{name}] cannot start: {exc}', file=sys.stderr, flush=True)
                raise SystemExit(1) from None
            line = startup_error_line(exc) if node is None else None
            if line is None:
                raise
            print(line, file=sys.stderr, flush=True)
            raise SystemExit(2) from None
        # else: the context was shut down (a signal) under start-up or a callback: a stop
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
        try:
            if node is not None:
                node.destroy_node()
        finally:
            rclpy.try_shutdown()


def main_for(node_factory: Callable[[], Any], *,
             cannot_start: tuple[type[BaseException], ...] = ()) -> Callable[..., None]:
    """A console-script main(args=None) that runs node_factory (see run). As the process's
    entry point (args None) it binds 127.0.0.1 first and ends the process without the
    interpreter's finalization (process_exit.py says why)."""
    def main(args: list[str] | None = None) -> None:
        if args is not None:
            run(node_factory, args, cannot_start=cannot_start)
            return
        exec_loopback_bound()
        run_then_exit(lambda: run(node_factory, None, cannot_start=cannot_start))

    name = getattr(node_factory, '__name__', 'the node')
    main.__doc__ = f'Run {name} until Ctrl-C (or SIGTERM, or shutdown).'
    return main


__all__ = ['Check', 'CheckAll', 'LatestWorker', 'Param', 'ParameterError', 'ParameterTable',
           'declare_parameters', 'guarded', 'has_subscribers', 'main_for', 'publish_from_thread',
           'replace_timer',
           'run',
           'startup_error_line']
