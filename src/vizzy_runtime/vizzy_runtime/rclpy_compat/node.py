"""rclpy.node.Node on Cyclone DDS: publishers, subscriptions, timers, parameters, logger, clock.

Callbacks run in the executor's thread (spin), never in Cyclone's threads: the executor waits on
a Cyclone waitset that each subscription's reader triggers while it holds samples (no Python
listener per sample; the node's /clock, "direct", is the exception: see Subscription).
"""

from __future__ import annotations

import itertools
import math
import struct
import threading
import time as _time
from collections.abc import Callable, Iterable
from typing import Any

from .. import dds, msgs
from . import exceptions as exc
from . import (
    graph,  # ros_discovery_info (graph hooks below are marked "graph hook")
    param_services,  # rcl_interfaces parameter services ("parameter services hook")
)
from .context import Context, get_default_context
from .duration import Duration
from .logging import RcutilsLogger, add_rosout_sink, remove_rosout_sink
from .names import expand, normalize_namespace, remap, validate_node_name
from .parameter import (
    FloatingPointRange,
    IntegerRange,
    Parameter,
    ParameterDescriptor,
    SetParametersResult,
)
from .qos import (
    QoSProfile,
    as_profile,
    qos_profile_clock,
    qos_profile_parameter_events,
    qos_profile_rosout_default,
)
from .time import Clock, ROSClock

ParameterEvent = msgs.get_message('rcl_interfaces/msg/ParameterEvent')


class Publisher:
    def __init__(self, node: Node, msg_type: type, topic: str, qos: QoSProfile) -> None:
        self.msg_type = msg_type
        self.typename = msgs.type_of(msg_type)
        self.topic = topic
        self.qos_profile = qos
        self._node = node
        self._destroyed = False
        self._writer = dds.RawWriter(topic, self.typename, qos.to_dds())

    @property
    def topic_name(self) -> str:
        return self.topic

    @property
    def guid(self) -> bytes:
        return self._writer.guid

    def publish(self, msg: Any) -> None:
        """Publish a message of this publisher's type, or already serialized CDR bytes.

        As rclpy: InvalidHandle once the publisher (or its node) is destroyed, RCLError once its
        context is shut down; rclpy's signal handler shuts it down on SIGINT/SIGTERM before spin
        returns, and so does this runtime's (see rclpy_compat.init)."""
        if self._destroyed:
            raise exc.InvalidHandle('cannot use Destroyable because destruction was requested')
        if not self._node.context.ok():
            raise exc.RCLError("Failed to publish: publisher's context is invalid")
        if isinstance(msg, (bytes, bytearray, memoryview)):
            data: Any = msg
        elif msgs.type_of(msg) != self.typename:
            raise TypeError(f'{self._node.get_name()}: publisher on {self.topic} expects '
                            f'{self.typename}, got {msgs.type_of(msg)}')
        else:
            data = msgs.serialize(msg, self.typename)
        try:
            self._writer.write(data)
        except Exception:
            if self._destroyed:  # destroyed by another thread while this one wrote
                raise exc.InvalidHandle('cannot use Destroyable because destruction was '
                                        'requested') from None
            raise

    def get_subscription_count(self) -> int:
        return self._writer.matched_count()

    def wait_for_subscribers(self, count: int = 1, timeout_sec: float = 5.0) -> bool:
        """Block until `count` readers matched (discovery is asynchronous)."""
        deadline = _time.monotonic() + timeout_sec
        while self.get_subscription_count() < count:
            if _time.monotonic() > deadline:
                return False
            _time.sleep(0.005)
        return True

    def destroy(self) -> bool:
        return self._node.destroy_publisher(self)


# A subscription's malformed samples are logged at most this often [s] (each one is counted).
MALFORMED_LOG_PERIOD_S = 5.0
# Keys by which executors' waitsets name subscriptions (never reused, unlike id()).
_WAIT_KEYS = itertools.count(1)
_CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
_CLOCK_LE = struct.Struct('<iI')


def _decode_clock(raw: bytes | memoryview, typename: str = _CLOCK_TYPE) -> tuple[int, int]:
    """(sec, nanosec) of a rosgraph_msgs/Clock sample. A node reads 100 a second in the graph:
    the usual one (little-endian CDR, 8 bytes and up to 3 of padding) is read in place, with no
    message objects; any other goes through msgs.deserialize (its error for a malformed one)."""
    if 12 <= len(raw) <= 15 and raw[0] == 0 and raw[1] == 1:
        sec, nanosec = _CLOCK_LE.unpack_from(raw, 4)
        return sec, nanosec
    msg = msgs.deserialize(raw, typename)
    return int(msg.clock.sec), int(msg.clock.nanosec)


class Subscription:
    def __init__(self, node: Node, msg_type: type, topic: str, callback: Callable[[Any], None],
                 qos: QoSProfile, raw: bool, direct: bool = False,
                 decode: Callable[[Any, str], Any] | None = None) -> None:
        self.msg_type = msg_type
        # what the callback gets of each sample (msgs.deserialize: the message; a ValueError or
        # rosbags' SerdeError: counted and logged as malformed)
        self._decode = decode or msgs.deserialize
        # direct: the callback runs in Cyclone's listener thread as the data arrives, not in the
        # executor (for /clock: a tick needs no executor wake-up unless a timer is due)
        self.direct = direct
        self._direct_lock = threading.Lock()
        self.typename = msgs.type_of(msg_type)
        self.topic = topic
        self.callback = callback
        self.qos_profile = qos
        self.raw = raw
        self.malformed = 0  # samples that could not be decoded (counted, logged throttled)
        self._malformed_logged = -math.inf
        self._node = node
        self._ready = True  # take whatever arrived before the executor first waited
        self._wait_key = next(_WAIT_KEYS)
        # a direct subscription's listener dispatches; the others have none: the executor's
        # waitset wakes it and says which readers hold samples (Executor._wait)
        self._reader = dds.RawReader(topic, self.typename, qos.to_dds(),
                                     on_data=self._on_data if direct else None)
        if direct:
            self._dispatch_direct()       # what arrived while the reader was being made

    @property
    def topic_name(self) -> str:
        return self.topic

    @property
    def guid(self) -> bytes:
        return self._reader.guid

    def _on_data(self, _reader: dds.RawReader) -> None:
        """A direct subscription's listener (Cyclone's thread)."""
        self._ready = True
        if hasattr(self, '_reader'):      # (not while the reader is being made: __init__ takes)
            self._dispatch_direct()

    def _dispatch_direct(self) -> None:
        with self._direct_lock:
            self._take_and_dispatch()

    def get_publisher_count(self) -> int:
        return self._reader.matched_count()

    def wait_for_publishers(self, count: int = 1, timeout_sec: float = 5.0) -> bool:
        deadline = _time.monotonic() + timeout_sec
        while self.get_publisher_count() < count:
            if _time.monotonic() > deadline:
                return False
            _time.sleep(0.005)
        return True

    def take_and_dispatch(self, limit: int = 256) -> int:
        """Run the callback for each waiting sample. A sample that cannot be decoded is logged and
        skipped; an exception in the user callback is logged and does not stop the node. (A
        direct subscription dispatches in the listener thread: nothing for the executor.)"""
        return 0 if self.direct else self._take_and_dispatch(limit)

    def _take_and_dispatch(self, limit: int = 256) -> int:
        if not self._ready:
            return 0
        self._ready = False
        samples = self._reader.take(limit)
        if len(samples) == limit:
            self._ready = True
        for raw, _stamp in samples:
            if self.raw:
                message: Any = raw
            else:
                try:
                    message = self._decode(raw, self.typename)
                except Exception as err:  # noqa: BLE001 - one bad message never kills a node
                    self.malformed += 1
                    now = _time.monotonic()
                    if now - self._malformed_logged >= MALFORMED_LOG_PERIOD_S:
                        self._malformed_logged = now
                        self._node.get_logger().error(
                            f'{self.topic}: dropped a malformed {self.typename} ({len(raw)} bytes, '
                            f'{self.malformed} so far): {err}')
                    continue
            self._node._run_callback(self.callback, message, f'subscription {self.topic}')
        return len(samples)

    def destroy(self) -> bool:
        return self._node.destroy_subscription(self)


class Timer:
    def __init__(self, node: Node, period_sec: float, callback: Callable[[], Any], clock: Clock,
                 autostart: bool = True) -> None:
        if not period_sec > 0 or not math.isfinite(period_sec):
            raise ValueError('timer period must be a positive number of seconds, got '
                             f'{period_sec!r}')
        self.timer_period_ns = int(period_sec * 1e9)
        self.callback = callback
        self.clock = clock
        # the clock's time [ns]; a clock of another kind than ours: through now()
        self._now_ns: Callable[[], int] = getattr(clock, '_now_ns', None) or (
            lambda: clock.now().nanoseconds)
        self._node = node
        self._canceled = not autostart
        self._next = self._now_ns() + self.timer_period_ns

    def is_canceled(self) -> bool:
        return self._canceled

    def cancel(self) -> None:
        self._canceled = True

    def reset(self) -> None:
        self._canceled = False
        self._next = self._now_ns() + self.timer_period_ns
        self._node.context.notify()

    def is_ready(self) -> bool:
        return not self._canceled and self.time_until_next_call() <= 0

    def time_until_next_call(self) -> int:
        now = self._now_ns()
        if now + self.timer_period_ns < self._next - self.timer_period_ns:
            self._next = now + self.timer_period_ns  # the clock jumped back (sim time restarted)
        return self._next - now

    def call(self) -> None:
        now = self._now_ns()
        missed = max(0, (now - self._next) // self.timer_period_ns)
        self._next += (missed + 1) * self.timer_period_ns
        self._node._run_callback(self.callback, None, 'timer')

    def destroy(self) -> bool:
        return self._node.destroy_timer(self)


class Node:
    """rclpy.node.Node (the subset our nodes use, same signatures)."""

    PARAM_REL_TOL = 1e-6

    def __init__(self, node_name: str, *, context: Context | None = None,
                 cli_args: list[str] | None = None, namespace: str | None = None,
                 use_global_arguments: bool = True, enable_rosout: bool = True,
                 start_parameter_services: bool = True,
                 parameter_overrides: list[Parameter] | None = None,
                 allow_undeclared_parameters: bool = False,
                 automatically_declare_parameters_from_overrides: bool = False,
                 enable_logger_service: bool = False) -> None:
        from . import arguments
        if enable_logger_service:   # rclpy's get/set_logger_levels services (`ros2 logger`)
            raise NotImplementedError('Node(enable_logger_service=True): the bundled runtime has '
                                      'no logger services (see rclpy_compat/README.md)')
        self.context = context or get_default_context()
        if not self.context.ok():
            raise RuntimeError('rclpy.init() has not been called (or the context was shut down)')
        local = arguments.parse(['--ros-args', *cli_args] if cli_args
                                and '--ros-args' not in cli_args
                                else cli_args)
        merged = arguments.RosArguments()
        if use_global_arguments:
            merged.remaps.extend(self.context.args.remaps)
            merged.params.extend(self.context.args.params)
        merged.remaps[:0] = local.remaps  # node-local rules take precedence
        merged.params.extend(local.params)
        self._args = merged

        validate_node_name(node_name)
        self._name = merged.node_name(node_name)
        validate_node_name(self._name)
        self._namespace = normalize_namespace(merged.namespace(node_name, namespace or '/'))
        self._logger = RcutilsLogger(self._logger_name())
        self._lock = threading.RLock()
        self.publishers: list[Publisher] = []
        self.subscriptions: list[Subscription] = []
        self.timers: list[Timer] = []
        self.services: list[Any] = []  # served by the executor (parameter services)
        self.clients: list[Any] = []  # their replies handled by the executor (parameter clients)
        self._clock = ROSClock()
        # sim time moved: wake the executor if a timer is due (Executor._wait_timeout relies on it)
        self._clock._on_change.append(self._on_clock_moved)
        self._clock.wakes_executor = True
        self._clock_seen_ns: int | None = None
        self._clock_sub: Subscription | None = None
        self.clock_refused = 0  # /clock samples that were no valid time
        self._destroyed = False
        self._type_warnings: set[tuple[str, str]] = set()
        # as rcl: the node's log records also go out on /rosout (rqt_console, Foxglove's log panel)
        self._rosout_publisher: Publisher | None = None
        if enable_rosout and self.context.args.rosout_logs:
            self._rosout_publisher = self.create_publisher(
                msgs.get_message('rcl_interfaces/msg/Log'), '/rosout', qos_profile_rosout_default)
            add_rosout_sink(self._logger.name, self._publish_rosout)

        self._parameters: dict[str, Parameter] = {}
        self._descriptors: dict[str, Any] = {}
        self._set_callbacks: list[Callable[[list[Parameter]], Any]] = []
        self._pre_set_callbacks: list[Callable[[list[Parameter]], list[Parameter]]] = []
        self._post_set_callbacks: list[Callable[[list[Parameter]], None]] = []
        # as rclpy: every declaration and accepted set is announced on /parameter_events
        self._parameter_event_publisher: Publisher | None = self.create_publisher(
            ParameterEvent, '/parameter_events', qos_profile_parameter_events)
        self._allow_undeclared = allow_undeclared_parameters
        self._overrides = merged.parameter_overrides(self.get_fully_qualified_name())
        for p in parameter_overrides or []:
            self._overrides[p.name] = p.value
        if automatically_declare_parameters_from_overrides:
            for name, value in self._overrides.items():
                if name != 'use_sim_time':
                    self.declare_parameter(name, value)
        self.declare_parameter('use_sim_time', False, ParameterDescriptor(
            description='Follow /clock (simulation or bag time) instead of the system clock.'))
        self.add_on_set_parameters_callback(self._on_use_sim_time)
        self._apply_sim_time(bool(self.get_parameter('use_sim_time').value))
        if start_parameter_services:  # parameter services hook: ros2 param get/set/list/describe
            param_services.start(self)
        with self.context.wake:
            self.context.nodes.append(self)
        graph.node_created(self)  # graph hook: announce the node on ros_discovery_info
        self.context.notify()

    # --- identity ---------------------------------------------------------------------------
    def get_name(self) -> str:
        return self._name

    def get_namespace(self) -> str:
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        return f'{self._namespace.rstrip("/")}/{self._name}'

    def _logger_name(self) -> str:
        ns = self._namespace.strip('/').replace('/', '.')
        return f'{ns}.{self._name}' if ns else self._name

    def get_logger(self) -> RcutilsLogger:
        return self._logger

    def get_clock(self) -> Clock:
        return self._clock

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        fqn = expand(topic, self._name, self._namespace)
        return fqn if only_expand else remap(fqn, self._args.remaps, self._name, self._namespace)

    # --- entities ---------------------------------------------------------------------------
    def create_publisher(self, msg_type: type, topic: str, qos_profile: QoSProfile | int, *,
                         callback_group: Any = None, event_callbacks: Any = None,
                         qos_overriding_options: Any = None,
                         publisher_class: type[Publisher] = Publisher) -> Publisher:
        """rclpy's signature; callback_group is accepted (every callback runs in the executor's
        one thread: rclpy's mutually exclusive group); the rest are refused unless left at
        their default (rclpy_compat/README.md)."""
        _refuse_unsupported('create_publisher', event_callbacks=event_callbacks,
                            qos_overriding_options=qos_overriding_options)
        if publisher_class is not Publisher:
            raise NotImplementedError(f'create_publisher(publisher_class={publisher_class!r}): '
                                      'the bundled runtime makes only its own Publisher')
        pub = Publisher(self, msg_type, self.resolve_topic_name(topic), as_profile(qos_profile))
        with self._lock:
            self.publishers.append(pub)
        graph.node_changed(self)  # graph hook: republish this node's writers
        self.context.notify()
        return pub

    def create_subscription(self, msg_type: type, topic: str, callback: Callable[[Any], None],
                            qos_profile: QoSProfile | int, *, callback_group: Any = None,
                            event_callbacks: Any = None, qos_overriding_options: Any = None,
                            raw: bool = False) -> Subscription:
        """rclpy's signature; raw (serialized bytes to the callback) and callback_group (see
        create_publisher) are honoured, event_callbacks and qos_overriding_options refused."""
        _refuse_unsupported('create_subscription', event_callbacks=event_callbacks,
                            qos_overriding_options=qos_overriding_options)
        return self._create_subscription(msg_type, topic, callback, qos_profile, raw=raw)

    def _create_subscription(self, msg_type: type, topic: str, callback: Callable[[Any], None],
                             qos_profile: QoSProfile | int, *, raw: bool = False,
                             direct: bool = False,
                             decode: Callable[[Any, str], Any] | None = None) -> Subscription:
        """direct: the callback runs in the DDS listener thread (this runtime's /clock only);
        decode(raw, typename): what the callback gets instead of the message."""
        sub = Subscription(self, msg_type, self.resolve_topic_name(topic), callback,
                           as_profile(qos_profile), raw, direct, decode)
        with self._lock:
            self.subscriptions.append(sub)
        graph.node_changed(self)  # graph hook: republish this node's readers
        self.context._subscriptions_changed()
        return sub

    def create_timer(self, timer_period_sec: float, callback: Callable[[], Any],
                     callback_group: Any = None, clock: Clock | None = None,
                     autostart: bool = True) -> Timer:
        timer = Timer(self, timer_period_sec, callback, clock or self._clock, autostart)
        with self._lock:
            self.timers.append(timer)
        self.context.notify()
        return timer

    def destroy_publisher(self, publisher: Publisher) -> bool:
        with self._lock:
            if publisher not in self.publishers:
                return False
            self.publishers.remove(publisher)
            publisher._destroyed = True
        dds.delete(publisher._writer)
        graph.node_changed(self)  # graph hook: republish this node's writers
        return True

    def destroy_subscription(self, subscription: Subscription) -> bool:
        with self._lock:
            if subscription not in self.subscriptions:
                return False
            self.subscriptions.remove(subscription)
        self.context._subscriptions_changed()    # executors stop watching it
        dds.delete(subscription._reader)
        graph.node_changed(self)  # graph hook: republish this node's readers
        return True

    def destroy_timer(self, timer: Timer) -> bool:
        with self._lock:
            if timer not in self.timers:
                return False
            timer.cancel()
            self.timers.remove(timer)
        return True

    def destroy_node(self) -> None:
        if self._destroyed:
            return
        self._destroyed = True
        remove_rosout_sink(self._logger.name, self._publish_rosout)
        self._rosout_publisher = None  # destroyed with the other publishers below
        param_services.stop(self)  # parameter services hook: their readers, writers and timer go
        for client in list(self.clients):
            client.destroy()
        self._parameter_event_publisher = None  # destroyed with the other publishers below
        for pub in list(self.publishers):
            self.destroy_publisher(pub)
        for sub in list(self.subscriptions):
            self.destroy_subscription(sub)
        for timer in list(self.timers):
            self.destroy_timer(timer)
        with self.context.wake:
            if self in self.context.nodes:
                self.context.nodes.remove(self)
        graph.node_destroyed(self)  # graph hook: the node leaves ros_discovery_info
        self.context.notify()

    def _publish_rosout(self, stamp_ns: int, level: int, name: str, msg: str, file: str,
                        function: str, line: int) -> None:
        """The logger's /rosout sink: one rcl_interfaces/msg/Log per record, dropped once the
        context is shut down (rcl can no longer publish it either)."""
        publisher = self._rosout_publisher
        if publisher is None or not self.context.ok():
            return
        record = publisher.msg_type(level=level, name=name, msg=msg, file=file,
                                    function=function, line=line)
        record.stamp.sec, record.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        publisher.publish(record)

    def _run_callback(self, callback: Callable[..., Any], arg: Any, what: str) -> None:
        try:
            callback() if what == 'timer' else callback(arg)
        except (KeyboardInterrupt, SystemExit, exc.ExternalShutdownException):
            raise
        except Exception as err:  # noqa: BLE001 - keep the node alive, say what failed
            self._logger.error(f'{what} callback raised {type(err).__name__}: {err}')

    # --- graph ------------------------------------------------------------------------------
    def get_topic_names_and_types(self, no_demangle: bool = False) -> list[tuple[str, list[str]]]:
        topics: dict[str, set[str]] = {}
        for ep in self.context.discovery().endpoints():
            topics.setdefault(ep.topic, set()).add(ep.typename)
        return sorted((t, sorted(types)) for t, types in topics.items())

    def check_topic_types(self) -> None:
        """Warn (once per topic and type) about peers using one of our topics with another type:
        DDS never matches them, so without this the data would just not arrive."""
        endpoints: tuple[Publisher | Subscription, ...] = (*self.publishers, *self.subscriptions)
        ours = {e.topic: e.typename for e in endpoints}
        warned = self._type_warnings
        for ep in self.context.discovery().endpoints():
            want = ours.get(ep.topic)
            if want and ep.typename != want and (ep.topic, ep.typename) not in warned:
                warned.add((ep.topic, ep.typename))
                role = 'publishes' if ep.is_writer else 'subscribes to'
                self._logger.warning(f'[{ep.topic}] a peer {role} it as {ep.typename}, this node '
                                     'uses '
                                     f'{want}: the two will not connect')

    def count_publishers(self, topic_name: str) -> int:
        fqn = self.resolve_topic_name(topic_name)
        return sum(1 for ep in self.context.discovery().endpoints() if ep.is_writer
                   and ep.topic == fqn)

    def count_subscribers(self, topic_name: str) -> int:
        fqn = self.resolve_topic_name(topic_name)
        return sum(1 for ep in self.context.discovery().endpoints() if not ep.is_writer
                   and ep.topic == fqn)

    # --- parameters -------------------------------------------------------------------------
    # rclpy's semantics (rclpy/node.py, Jazzy): a declaration or a set first applies the
    # descriptor (read-only, the static type, the first integer/floating-point range: inclusive,
    # the edges within PARAM_REL_TOL), then the on-set callbacks (newest first; the first refusal
    # wins); only then are the values stored, announced on /parameter_events and handed to the
    # post-set callbacks (newest first). Pre-set callbacks (set_parameters* only) may replace the
    # list before all that. Reasons and exceptions carry rclpy's texts.
    def declare_parameter(self, name: str, value: Any = None, descriptor: Any = None,
                          ignore_override: bool = False) -> Parameter:
        if name in self._parameters:
            raise exc.ParameterAlreadyDeclaredException([name])
        descriptor = descriptor or ParameterDescriptor()
        descriptor.name = name
        if isinstance(value, Parameter.Type):
            declared_type, value = value, None
        elif value is None:
            declared_type = (Parameter.Type(descriptor.type) if descriptor.type
                             else Parameter.Type.NOT_SET)
        else:
            declared_type = Parameter.Type.from_parameter_value(value)
        if descriptor.type == 0 and not descriptor.dynamic_typing:
            descriptor.type = int(declared_type)
        if not ignore_override and name in self._overrides:
            value = self._coerce(name, self._overrides[name], Parameter.Type(descriptor.type))
        param = Parameter(name, Parameter.Type.from_parameter_value(value) if value is not None
                          else Parameter.Type.NOT_SET, value)
        result = self._set_parameters_common([param], {name: descriptor})
        if not result.successful:
            if result.reason.startswith('Wrong parameter type'):
                raise exc.InvalidParameterTypeException(param, Parameter.Type(descriptor.type).name)
            raise exc.InvalidParameterValueException(name, value, result.reason)
        return self._parameters[name]

    def declare_parameters(self, namespace: str, parameters: Iterable[tuple],
                           ignore_override: bool = False) -> list[Parameter]:
        out = []
        for entry in parameters:
            name = f'{namespace}.{entry[0]}' if namespace else entry[0]
            value = entry[1] if len(entry) > 1 else None
            descriptor = entry[2] if len(entry) > 2 else None
            out.append(self.declare_parameter(name, value, descriptor, ignore_override))
        return out

    def undeclare_parameter(self, name: str) -> None:
        if name not in self._parameters:
            raise exc.ParameterNotDeclaredException(name)
        if self._descriptors[name].read_only:
            raise exc.ParameterImmutableException(name)
        del self._parameters[name]
        del self._descriptors[name]

    def has_parameter(self, name: str) -> bool:
        return name in self._parameters

    def get_parameter(self, name: str) -> Parameter:
        if name in self._parameters:
            return self._parameters[name]
        if self._allow_undeclared:
            return Parameter(name, Parameter.Type.NOT_SET, None)
        raise exc.ParameterNotDeclaredException(name)

    def get_parameters(self, names: Iterable[str]) -> list[Parameter]:
        return [self.get_parameter(n) for n in names]

    def get_parameter_or(self, name: str, alternative_value: Parameter | None = None) -> Parameter:
        if name in self._parameters:
            return self._parameters[name]
        return alternative_value or Parameter(name, Parameter.Type.NOT_SET, None)

    def describe_parameter(self, name: str) -> Any:
        if name not in self._descriptors:
            raise exc.ParameterNotDeclaredException(name)
        return self._descriptors[name]

    def add_pre_set_parameters_callback(
            self, callback: Callable[[list[Parameter]], list[Parameter]]) -> None:
        """callback(parameters) -> the parameters to set instead (set_parameters* only)."""
        if not callable(callback):
            raise TypeError(f'Callback must be callable, got {type(callback)}')
        self._pre_set_callbacks.insert(0, callback)

    def remove_pre_set_parameters_callback(
            self, callback: Callable[[list[Parameter]], list[Parameter]]) -> None:
        self._pre_set_callbacks.remove(callback)

    def add_on_set_parameters_callback(self, callback: Callable[[list[Parameter]], Any]) -> None:
        if not callable(callback):
            raise TypeError(f'Callback must be callable, got {type(callback)}')
        self._set_callbacks.insert(0, callback)

    def remove_on_set_parameters_callback(self, callback: Callable[[list[Parameter]], Any]) -> None:
        self._set_callbacks.remove(callback)

    def add_post_set_parameters_callback(self, callback: Callable[[list[Parameter]], None]) -> None:
        """callback(parameters) after they were set (declared or changed), to act on them."""
        if not callable(callback):
            raise TypeError(f'Callback must be callable, got {type(callback)}')
        self._post_set_callbacks.insert(0, callback)

    def remove_post_set_parameters_callback(self,
                                            callback: Callable[[list[Parameter]], None]) -> None:
        self._post_set_callbacks.remove(callback)

    def set_parameters(self, parameter_list: list[Parameter]) -> list[Any]:
        """One result per parameter; raises ParameterNotDeclaredException at an undeclared one."""
        return [self._set_parameters_atomically([p]) for p in parameter_list]

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> Any:
        return self._set_parameters_atomically(parameter_list)

    def _set_parameters_atomically(self, parameter_list: list[Parameter]) -> Any:
        if self._pre_set_callbacks:
            modified: list[Parameter] = []
            for callback in list(self._pre_set_callbacks):
                modified.extend(callback(parameter_list))
            parameter_list = modified
            if not parameter_list:
                return SetParametersResult(
                    successful=False, reason='parameter list cannot be empty, this might be due to '
                    'pre_set_parameters_callback modifying the original parameters list.')
        if not self._allow_undeclared:
            undeclared = [p.name for p in parameter_list if p.name not in self._parameters]
            if undeclared:
                raise exc.ParameterNotDeclaredException(undeclared)
        return self._set_parameters_common(parameter_list)

    def _set_parameters_common(self, params: list[Parameter],
                               descriptors: dict[str, Any] | None = None) -> Any:
        """Descriptors given: a declaration (no read-only check; these descriptors are kept)."""
        table = self._descriptors if descriptors is None else descriptors
        for param in params:
            if param.name in table:
                result = self._apply_descriptor(param, table[param.name], descriptors is None)
                if not result.successful:
                    return result
        for callback in list(self._set_callbacks):
            result = callback(params)
            if result is None or not hasattr(result, 'successful'):
                return SetParametersResult(successful=False,
                                           reason='Callback returned an invalid type')
            if not result.successful:
                return SetParametersResult(successful=False, reason=result.reason)
        event = ParameterEvent(node=self.get_fully_qualified_name())
        for param in params:
            if descriptors is None and param.type_ == Parameter.Type.NOT_SET:
                event.deleted_parameters.append(param.to_parameter_msg())  # set to nothing: gone
                self._parameters.pop(param.name, None)
                self._descriptors.pop(param.name, None)
                continue
            if descriptors is not None:
                self._descriptors[param.name] = descriptors[param.name]
            elif param.name not in self._descriptors:  # an undeclared one, where allowed
                self._descriptors[param.name] = ParameterDescriptor(
                    name=param.name, type=int(param.type_), dynamic_typing=True)
            old = self._parameters.get(param.name)
            new = old is None or old.type_ == Parameter.Type.NOT_SET
            (event.new_parameters if new
             else event.changed_parameters).append(param.to_parameter_msg())
            self._parameters[param.name] = param
        event.stamp = self._clock.now().to_msg()
        if self._parameter_event_publisher is not None:
            self._parameter_event_publisher.publish(event)
        for post in list(self._post_set_callbacks):
            post(params)
        return SetParametersResult(successful=True)

    def _coerce(self, name: str, value: Any, declared: Parameter.Type) -> Any:
        if (declared == Parameter.Type.DOUBLE and isinstance(value, int)
                and not isinstance(value, bool)):
            return float(value)
        if declared == Parameter.Type.DOUBLE_ARRAY and isinstance(value, list):
            return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                    for v in value]
        return value

    def _apply_descriptor(self, param: Parameter, descriptor: Any, check_read_only: bool) -> Any:
        """rclpy's Node._apply_descriptor: whether descriptor admits param (nothing is stored)."""
        descriptor.name = param.name
        if check_read_only and descriptor.read_only:
            return SetParametersResult(
                successful=False, reason=f'Trying to set a read-only parameter: {param.name}.')
        if descriptor.dynamic_typing:
            descriptor.type = int(param.type_)
        elif param.name in self._parameters and param.type_ == Parameter.Type.NOT_SET:
            return SetParametersResult(successful=False,
                                       reason='Static parameter cannot be undeclared')
        elif param.type_ != Parameter.Type.NOT_SET and int(param.type_) != descriptor.type:
            return SetParametersResult(
                successful=False, reason=f"Wrong parameter type, expected "
                f"'Type.{Parameter.Type(descriptor.type).name}' got 'Type.{param.type_.name}'")
        if param.type_ == Parameter.Type.INTEGER and len(descriptor.integer_range):
            return _apply_range(param, descriptor.integer_range[0], False)
        if param.type_ == Parameter.Type.DOUBLE and len(descriptor.floating_point_range):
            return _apply_range(param, descriptor.floating_point_range[0], True)
        return SetParametersResult(successful=True)

    # --- sim time ---------------------------------------------------------------------------
    def _on_use_sim_time(self, params: list[Parameter]) -> Any:
        for p in params:
            if p.name == 'use_sim_time' and p.value is not None:
                if p.type_ != Parameter.Type.BOOL:
                    return SetParametersResult(successful=False,
                                               reason='use_sim_time must be a bool')
                if 'use_sim_time' in self._parameters:
                    self._apply_sim_time(bool(p.value))
        return SetParametersResult(successful=True)

    def _apply_sim_time(self, enabled: bool) -> None:
        """As rclpy's TimeSource: ROS time on, read from /clock (zero until the first message,
        so timers on the node's clock do not fire before it), or off (system time; the last
        /clock is kept for when it is turned on again)."""
        if enabled and self._clock_sub is None:
            clock_type = msgs.get_message(_CLOCK_TYPE)
            self._clock_sub = self._create_subscription(clock_type, '/clock', self._on_clock,
                                                        qos_profile_clock, direct=True,
                                                        decode=_decode_clock)
        elif not enabled and self._clock_sub is not None:
            self.destroy_subscription(self._clock_sub)
            self._clock_sub = None
        self._clock._set_ros_time_is_active(enabled)

    def _on_clock(self, clock: tuple[int, int]) -> None:
        """A /clock sample (sec, nanosec: _decode_clock) moves the node's ROS time; one that is no
        valid time (negative, or nanosec beyond a second) is refused with a warning (the first,
        then every 100th) and counted in clock_refused, so junk on /clock cannot stop the
        node."""
        sec, nanosec = clock
        if sec < 0 or not 0 <= nanosec < 1_000_000_000:
            self.clock_refused += 1
            if self.clock_refused % 100 == 1:
                self.get_logger().warning(
                    f'/clock: refused sample {self.clock_refused} (sec={sec}, nanosec={nanosec}): '
                    'not a valid time; the clock keeps its last value')
            return
        self._clock._set_ros_time_ns(sec * 1_000_000_000 + nanosec)

    def _on_clock_moved(self) -> None:
        """The node's clock changed (a /clock sample, in the listener thread; ROS time turned on
        or off): wake the executor when a timer on it is due or the clock went back (timers
        re-arm), not at every /clock tick (100 a second in the graph, each wake-up ~0.1 ms CPU)."""
        clock = self._clock
        now = clock._ros_time_ns if clock.ros_time_is_active else None
        last, self._clock_seen_ns = self._clock_seen_ns, now
        if now is None or last is None or now < last:
            self.context.notify()
            return
        for timer in list(self.timers):
            if timer.clock is clock and not timer.is_canceled() and timer._next <= now:
                self.context.notify()
                return


def _refuse_unsupported(where: str, **given: Any) -> None:
    """rclpy keywords this runtime does not implement: refused when set, never silently
    ignored (issue 30); None, their default, is fine."""
    for name, value in given.items():
        if value is not None:
            raise NotImplementedError(f'{where}({name}=...): not supported by the bundled runtime '
                                      '(see vizzy_runtime/rclpy_compat/README.md)')


def _apply_range(param: Parameter, rng: Any, is_float: bool) -> Any:
    """rclpy's _apply_integer_range / _apply_floating_point_range: inclusive bounds, the edges
    within Node.PARAM_REL_TOL (floats), an optional step from the lower bound; NaN is refused."""
    lo, hi = min(rng.from_value, rng.to_value), max(rng.from_value, rng.to_value)
    value, name = param.value, param.name

    def at(bound: float) -> bool:
        return math.isclose(value, bound,
                            rel_tol=Node.PARAM_REL_TOL) if is_float else value == bound

    if at(lo) or at(hi):
        return SetParametersResult(successful=True)
    if not lo < value < hi:
        return SetParametersResult(successful=False, reason=(
            f'Parameter {name} out of range{" " if is_float else ". "}Min: {lo}, Max: {hi}, value: '
            f'{value}'))
    if rng.step:
        k = round((value - lo) / rng.step)
        off = not math.isclose(lo + k * rng.step, value, rel_tol=Node.PARAM_REL_TOL) if is_float \
            else (value - lo) % rng.step != 0
        if off:
            return SetParametersResult(successful=False, reason=(
                f'The parameter value for {name} is not {"close enough to " if is_float else ""}a '
                f'valid step. Min: {lo}, max: {hi}, value: {value}, step: {rng.step}'))
    return SetParametersResult(successful=True)


__all__ = ['Node', 'Publisher', 'Subscription', 'Timer', 'Duration', 'FloatingPointRange',
           'IntegerRange']
