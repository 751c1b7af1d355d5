"""Driving a lock-stepped simulation: time advances only once the graph has done its work.

The sim with `lockstep:=true` advances as far as it is asked on `sim/step` and says so on
`sim/stepped` (vizzy_sim_bridge's sim node). :class:`Conductor` asks for one /clock tick at a
time and, before asking for the next, waits until every process of the graph is idle
(:class:`Quiescence`: no thread of theirs runnable, from /proc). So each node handles every
message a tick brought, however long that takes on this machine, and a run gives the same
answers on a loaded machine as on an idle one, only later (what the nodes decide still
depends on their own rates in sim time and on the order DDS delivers in).

Linux only (/proc). A node's wall-clock sleeps would escape it; the nodes of this graph pace
themselves by their stamps and the ROS clock instead.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from vizzy_runtime.ros import Context, QoSProfile, SingleThreadedExecutor, message

Clock = message('rosgraph_msgs/msg/Clock')

STEP_TOPIC = 'sim/step'
STEPPED_TOPIC = 'sim/stepped'
#: a thread in one of these states is doing something (running or runnable, or in disk sleep)
BUSY_STATES = frozenset('RD')


def _thread_states(pid: int) -> list[str]:
    """The scheduler state letter of each thread of process pid ([] when it is gone)."""
    states: list[str] = []
    try:
        tids = os.listdir(f'/proc/{pid}/task')
    except OSError:
        return states
    for tid in tids:
        try:
            with open(f'/proc/{pid}/task/{tid}/stat', 'rb') as f:
                raw = f.read()
        except OSError:
            continue                      # the thread ended meanwhile
        end = raw.rfind(b')')             # comm may hold spaces and parentheses
        if end > 0 and end + 2 < len(raw):
            states.append(chr(raw[end + 2]))
    return states


def process_cpu_seconds(pid: int) -> float | None:
    """User + system CPU time [s] of process pid so far (all its threads), None when gone."""
    try:
        with open(f'/proc/{pid}/stat', 'rb') as f:
            raw = f.read()
    except OSError:
        return None
    fields = raw[raw.rfind(b')') + 2:].split()
    ticks = os.sysconf('SC_CLK_TCK')
    return (int(fields[11]) + int(fields[12])) / ticks      # utime, stime (fields 14 and 15)


class Quiescence:
    """Waits until processes are idle: no thread of theirs runnable in `polls` consecutive looks
    `interval_s` apart."""

    def __init__(self, pids: Callable[[], Iterable[int]], *, polls: int = 2,
                 interval_s: float = 0.001) -> None:
        self.pids = pids
        self.polls = polls
        self.interval_s = interval_s
        self.waits = 0
        self.looks = 0

    def busy_threads(self) -> int:
        self.looks += 1
        return sum(s in BUSY_STATES for pid in self.pids() for s in _thread_states(pid))

    def wait(self, timeout_s: float = 30.0) -> bool:
        """True once idle; False if still busy after timeout_s (the caller goes on)."""
        self.waits += 1
        deadline = time.monotonic() + timeout_s
        quiet = 0
        while True:
            quiet = quiet + 1 if self.busy_threads() == 0 else 0
            if quiet >= self.polls:
                return True
            if time.monotonic() > deadline:
                return False
            time.sleep(self.interval_s)


class Conductor:
    """Asks a lock-stepped sim for one tick at a time, waiting for the graph in between.

    node: a node of this process (either rclpy) spun by an executor in another thread; pids:
    the graph's processes (the sim included). The topics are relative to node's namespace.
    """

    def __init__(self, node: Any, pids: Callable[[], Iterable[int]], *, tick_s: float = 0.01,
                 quiescence: Quiescence | None = None) -> None:
        self.node = node
        self.tick_s = float(tick_s)
        self.quiescence = quiescence or Quiescence(pids)
        self._cond = threading.Condition()
        self.reached = 0.0                   # the sim time the sim said it reached
        self.late_ticks = 0                  # ticks after which the graph never went idle
        qos = QoSProfile(depth=10)
        self._pub = node.create_publisher(Clock, STEP_TOPIC, qos)
        self._sub = node.create_subscription(Clock, STEPPED_TOPIC, self._on_stepped, qos)

    def _on_stepped(self, msg: Any) -> None:
        t = msg.clock.sec + 1e-9 * msg.clock.nanosec
        with self._cond:
            self.reached = max(self.reached, t)
            self._cond.notify_all()

    def connected(self) -> bool:
        """Whether the sim listens (its step subscription and our stepped one matched)."""
        return (self._pub.get_subscription_count() > 0
                and self.node.count_publishers(self._sub.topic_name) > 0)

    def _ask(self, t: float) -> None:
        msg = Clock()
        sec = math.floor(t)
        msg.clock.sec, msg.clock.nanosec = int(sec), min(int(round((t - sec) * 1e9)), 999999999)
        self._pub.publish(msg)

    def step_to(self, t: float, *, timeout_s: float = 60.0,
                on_tick: Callable[[float], None] | None = None) -> float:
        """Advance tick by tick until sim time t, each tick's work done before the next;
        on_tick(time) after each. Returns the time reached. Raises TimeoutError when the sim
        does not answer within timeout_s (wall) of a request."""
        while self.reached + 1e-9 < t:
            target = min(t, self.reached + self.tick_s)
            self._ask(target)
            deadline = time.monotonic() + timeout_s
            with self._cond:
                while self.reached + 1e-9 < target:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        raise TimeoutError(f'the sim did not reach {target:.3f} s within '
                                           f'{timeout_s:g} s (it said {self.reached:.3f} s)')
                    self._cond.wait(min(left, 0.5))
            if not self.quiescence.wait(timeout_s):
                self.late_ticks += 1
            if on_tick is not None:
                on_tick(self.reached)
        return self.reached


@contextlib.contextmanager
def spun_node(make_node: Callable[[Any], Any], name: str) -> Iterator[Any]:
    """A benchmark's node (make_node(context)) in a context of its own, spun by a daemon thread
    while the with-block runs (its callbacks run there; a Conductor waits on them); destroyed
    with its context afterwards."""
    context = Context()
    context.init([name])
    node = make_node(context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(0.05)

    spinner = threading.Thread(target=spin, name=f'{name}_spin', daemon=True)
    spinner.start()
    try:
        yield node
    finally:
        stop.set()
        spinner.join(timeout=2.0)
        node.destroy_node()
        context.try_shutdown()


__all__ = ['BUSY_STATES', 'Conductor', 'Quiescence', 'STEPPED_TOPIC', 'STEP_TOPIC',
           'process_cpu_seconds', 'spun_node']
