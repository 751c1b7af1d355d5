"""vizzy_runtime.lockstep: idleness from /proc, and a conductor stepping a lock-stepped sim."""

from __future__ import annotations

import subprocess
import sys
import threading

import pytest

from vizzy_runtime.lockstep import Conductor, Quiescence, process_cpu_seconds
from vizzy_runtime.ros import Context, Node, Parameter, SingleThreadedExecutor, message
from vizzy_runtime.testing import no_renderer, scaled, wait_until

pytestmark = pytest.mark.slow  # starts processes or a whole graph, or takes more than ~5 s

Clock = message('rosgraph_msgs/msg/Clock')


def _child(code: str) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, '-c', code])


def test_a_busy_process_is_not_quiet_and_a_sleeping_one_is() -> None:
    busy = _child('while True: pass')
    idle = _child('import time; time.sleep(60)')
    try:
        assert wait_until(lambda: (process_cpu_seconds(busy.pid) or 0.0) > 0.05, scaled(30.0))
        assert not Quiescence(lambda: [busy.pid]).wait(timeout_s=0.2)
        quiet = Quiescence(lambda: [idle.pid], polls=3)
        assert quiet.wait(timeout_s=scaled(30.0)) and quiet.looks >= 3
        assert (process_cpu_seconds(idle.pid) or 0.0) < 5.0
    finally:
        busy.kill()
        idle.kill()
        busy.wait()
        idle.wait()
    assert process_cpu_seconds(busy.pid) is None            # gone: None, no error
    assert Quiescence(lambda: [busy.pid]).wait(timeout_s=scaled(1.0))   # nothing left to wait for


@pytest.mark.live
def test_the_conductor_steps_a_lockstep_sim_tick_by_tick() -> None:
    from vizzy_sim_bridge.core import render
    from vizzy_sim_bridge.sim_node import SimNode
    try:
        render.select_backend()
    except render.RendererUnavailable as exc:
        no_renderer(str(exc))
    ctx = Context()
    ctx.init(['test'])
    sim = SimNode(context=ctx, cli_args=['--ros-args', '-r', '__ns:=/conducted'],
                  parameter_overrides=[Parameter('width', value=64),
                                       Parameter('height', value=48),
                                       Parameter('rgbd_rate_hz', value=0.0),
                                       Parameter('lockstep', value=True)])
    node = Node('conductor', context=ctx, namespace='/conducted',
                start_parameter_services=False)
    clocks: list[float] = []
    node.create_subscription(Clock, 'clock',
                             lambda m: clocks.append(m.clock.sec + 1e-9 * m.clock.nanosec), 100)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sim)
    executor.add_node(node)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(0.02)

    spinner = threading.Thread(target=spin, daemon=True)
    try:
        conductor = Conductor(node, lambda: [], tick_s=0.01)
        spinner.start()
        assert wait_until(conductor.connected, scaled(30.0))
        ticks: list[float] = []
        assert conductor.step_to(0.1, on_tick=ticks.append) == pytest.approx(0.1)
        assert ticks == pytest.approx([0.01 * i for i in range(1, 11)])
        assert wait_until(lambda: len(clocks) >= 10, scaled(30.0))
        assert clocks[:10] == pytest.approx(ticks) and sim.ticks == 10
        assert conductor.quiescence.waits == 10 and conductor.late_ticks == 0
    finally:
        stop.set()
        spinner.join(timeout=scaled(5.0))
        executor.remove_node(node)
        executor.remove_node(sim)
        node.destroy_node()
        sim.destroy_node()
        ctx.try_shutdown()
