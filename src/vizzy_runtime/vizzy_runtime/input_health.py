"""What a node refused of its inputs: counted per topic and reason, logged without flooding, and
published on /diagnostics the ROS way (rqt_robot_monitor, Foxglove's diagnostics panels).

    self.health = InputHealth(self)                 # in the node's __init__
    self.health.refuse(self._image_topic, 'unknown encoding', f'{msg.encoding!r}')
    self.health.accept(self._image_topic)           # a message processed

The first refusal of each (topic, reason) is logged in one line naming node, topic and reason;
later ones at most once every throttle_s per (topic, reason), with the count so far. Every period_s
the node publishes one diagnostic_msgs/DiagnosticStatus (name: the node's full name) in a
DiagnosticArray on /diagnostics: WARN while refusals happened in the last period, else OK, with a
`<topic>: <reason>` = count entry for every reason seen and `<topic>: accepted` = count for every
topic that processed messages. On the bundled runtime, samples its subscriptions could not decode
(malformed CDR) are counted as the reason `malformed CDR`.

An output can also stop for a reason of the node's own, its inputs all fine: frames held back
during a saccade, a gaze state that never ends, a parameter. So a node also says

    self.health.hold(self._image_topic, 'in saccade')   # processed, output held back by design
    self.health.watch_output(out_topic, [self._image_topic], stall_s=lambda: 3.0)
    self.health.published(out_topic)                    # each time the output goes out

and the status is WARN while a watched output has not gone out for stall_s (the node's clock:
sim time under use_sim_time) although its inputs kept arriving, naming what happened to them
since (`no /foveation/image for 12.0 s while /camera/image_raw arrives: 180 held (in saccade)`).
Held inputs are shown as `<topic>: held (<reason>)` = count, and are never logged one by one.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from .ros import message, qos_profile_system_default

DIAGNOSTICS_TOPIC = '/diagnostics'  # absolute, as diagnostic_updater publishes it
MALFORMED = 'malformed CDR'


class ThrottledWarnings:
    """Warnings about what is no refused input (those go to InputHealth): one line at most every
    period_s per kind, so a fault that repeats at frame rate does not flood the log.

        self._warn_throttled = ThrottledWarnings(self, 5.0)
        self._warn_throttled('tf', f'no transform {frame} -> base_link: {exc}')
    """

    def __init__(self, node: Any, period_s: float = 5.0) -> None:
        self._node = node
        self._period_s = period_s
        self._lock = threading.Lock()
        self._last: dict[str, float] = {}

    def __call__(self, kind: str, text: str, period_s: float | None = None) -> bool:
        """Log text unless a warning of this kind was logged within the period; True if logged."""
        now = time.monotonic()
        period = self._period_s if period_s is None else period_s
        with self._lock:
            if now - self._last.get(kind, -math.inf) < period:
                return False
            self._last[kind] = now
        self._node.get_logger().warning(text)
        return True


@dataclass
class _Watch:
    """A watched output: its inputs, how long it may be silent, and what was counted when it last
    went out (to say what happened to the inputs since)."""
    inputs: tuple[str, ...]
    stall_s: Callable[[], float]
    last_out: float
    counts_at_out: dict[tuple[str, str], int] = field(default_factory=dict)


class InputHealth:
    """Refusal counters of one node, with their log lines and /diagnostics publisher."""

    def __init__(self, node: Any, *, period_s: float = 1.0, throttle_s: float = 5.0,
                 hardware_id: str = '') -> None:
        self._node = node
        self._throttle_s = throttle_s
        self._hardware_id = hardware_id
        self._lock = threading.Lock()
        self._refused: dict[tuple[str, str], int] = {}
        self._accepted: dict[str, int] = {}
        self._logged: dict[tuple[str, str], float] = {}
        self._refused_at_last_report = 0
        self._held: dict[tuple[str, str], int] = {}
        self._last_input: dict[str, float] = {}    # topic -> node-clock time of its last message
        self._watches: dict[str, _Watch] = {}
        self._array = message('diagnostic_msgs/msg/DiagnosticArray')
        self._status = message('diagnostic_msgs/msg/DiagnosticStatus')
        self._key_value = message('diagnostic_msgs/msg/KeyValue')
        self._publisher = node.create_publisher(self._array, DIAGNOSTICS_TOPIC,
                                                qos_profile_system_default)
        self._timer = node.create_timer(period_s, self._report_safely)

    # --- counting (any thread) ------------------------------------------------------------------

    def _now(self) -> float:
        """The node's clock [s] (sim time under use_sim_time: a paused sim stalls nothing)."""
        return float(self._node.get_clock().now().nanoseconds) * 1e-9

    def refuse(self, topic: str, reason: str, detail: str = '') -> None:
        """Count a refused input; log it (first time per topic and reason, then throttled)."""
        key = (topic, reason)
        now = time.monotonic()
        clock = self._now() if self._watches else 0.0
        with self._lock:
            count = self._refused.get(key, 0) + 1
            self._refused[key] = count
            self._last_input[topic] = clock
            due = now - self._logged.get(key, -math.inf) >= self._throttle_s
            if due:
                self._logged[key] = now
        if due:
            more = f' ({count} refused so far)' if count > 1 else ''
            text = f'{topic}: refused: {reason}' + (f': {detail}' if detail else '') + more
            self._node.get_logger().warning(text)

    def accept(self, topic: str) -> None:
        clock = self._now() if self._watches else 0.0
        with self._lock:
            self._accepted[topic] = self._accepted.get(topic, 0) + 1
            self._last_input[topic] = clock

    def hold(self, topic: str, reason: str) -> None:
        """Count an input processed whose output the node held back on purpose (no log line)."""
        clock = self._now() if self._watches else 0.0
        with self._lock:
            self._held[(topic, reason)] = self._held.get((topic, reason), 0) + 1
            self._last_input[topic] = clock

    def held(self) -> dict[tuple[str, str], int]:
        with self._lock:
            return dict(self._held)

    def watch_output(self, output: str, inputs: Sequence[str],
                     stall_s: Callable[[], float] | float) -> None:
        """WARN on /diagnostics while output has not gone out (published()) for stall_s seconds
        of the node's clock although one of inputs arrived within that time. stall_s may be a
        callable (read at each report: a parameter)."""
        limit = stall_s if callable(stall_s) else (lambda: float(stall_s))
        now = self._now()
        with self._lock:
            self._watches[output] = _Watch(tuple(inputs), limit, now)

    def published(self, output: str) -> None:
        """output went out (a watched output: its stall clock starts again)."""
        watch = self._watches.get(output)
        if watch is None:
            return
        now = self._now()
        with self._lock:
            watch.last_out = now
            watch.counts_at_out = self._counts()

    def _counts(self) -> dict[tuple[str, str], int]:
        """Held and refused counts, (topic, reason) keyed; refusals' reasons say so. Under _lock."""
        counts = dict(self._held)
        counts.update({(t, f'refused: {r}'): n for (t, r), n in self._refused.items()})
        return counts

    def stalls(self) -> list[str]:
        """One line per watched output that stalled (see watch_output), naming what its inputs
        met since it last went out."""
        if not self._watches:
            return []
        now = self._now()
        lines = []
        with self._lock:
            counts = self._counts()
            for output, watch in self._watches.items():
                limit = watch.stall_s()
                silent = now - watch.last_out
                arrived = [t for t in watch.inputs
                           if self._last_input.get(t, -math.inf) > watch.last_out
                           and self._last_input[t] >= now - limit]
                if silent <= limit or not arrived:
                    continue
                since = sorted(((n - watch.counts_at_out.get(key, 0), key[1])
                                for key, n in counts.items()
                                if key[0] in watch.inputs and n > watch.counts_at_out.get(key, 0)),
                               reverse=True)
                what = ', '.join(f'{n} {"" if r.startswith("refused") else "held "}({r})'
                                 for n, r in since[:3])
                lines.append(f'no {output} for {silent:.1f} s while {arrived[0]} arrives'
                             + (f': {what}' if what else ''))
        return lines

    def refused(self) -> dict[tuple[str, str], int]:
        """(topic, reason) -> count, the runtime's malformed samples included."""
        with self._lock:
            out = dict(self._refused)
        for sub in list(getattr(self._node, 'subscriptions', [])):
            malformed = getattr(sub, 'malformed', 0)
            if malformed:
                out[(sub.topic, MALFORMED)] = malformed
        return out

    def accepted(self) -> dict[str, int]:
        with self._lock:
            return dict(self._accepted)

    # --- /diagnostics ---------------------------------------------------------------------------

    def status(self) -> Any:
        """This node's DiagnosticStatus now (WARN if anything was refused since the last one)."""
        refused = self.refused()
        total = sum(refused.values())
        fresh = total - self._refused_at_last_report
        self._refused_at_last_report = total
        stalls = self.stalls()
        status = self._status()
        status.name = self._node.get_fully_qualified_name()
        status.hardware_id = self._hardware_id
        if fresh or stalls:
            status.level = self._status.WARN
            status.message = '; '.join(
                stalls + ([f'{fresh} input(s) refused in the last period, {total} in all']
                          if fresh else []))
        else:
            status.level = self._status.OK
            status.message = f'inputs OK ({total} refused in all)' if total else 'inputs OK'
        values = [self._key_value(key=f'{topic}: {reason}', value=str(count))
                  for (topic, reason), count in sorted(refused.items())]
        values += [self._key_value(key=f'{topic}: held ({reason})', value=str(count))
                   for (topic, reason), count in sorted(self.held().items())]
        values += [self._key_value(key=f'{topic}: accepted', value=str(count))
                   for topic, count in sorted(self.accepted().items())]
        status.values = values
        return status

    def report(self) -> None:
        array = self._array()
        array.header.stamp = self._node.get_clock().now().to_msg()
        array.status = [self.status()]
        self._publisher.publish(array)

    def _report_safely(self) -> None:
        try:
            self.report()
        except Exception as exc:  # noqa: BLE001 - a diagnostics failure never ends the node
            if not self._node.context.ok():
                return
            self.refuse(DIAGNOSTICS_TOPIC, 'report failed', f'{type(exc).__name__}: {exc}')
