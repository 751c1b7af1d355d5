"""node_tools.run(), the main of every node, as a process on the runtime under test: repeated
Ctrl-C during clean-up and bad start-up parameters end the node cleanly, in one line at most.

Under `ros2 launch` in a terminal each node gets SIGINT twice (from the terminal's process group
and from launch); on the real rclpy that used to raise KeyboardInterrupt inside destroy_node().
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time

import pytest

from vizzy_runtime.testing import scaled

# live: also run on the real rclpy (scripts/test_ros.sh); slow: each test starts a node process
pytestmark = [pytest.mark.live, pytest.mark.slow]

STARTUP_TIMEOUT = scaled(120.0)   # imports alone take tens of seconds on a loaded 2-core machine


def _node(*ros_args: str) -> subprocess.Popen[str]:
    cmd = [sys.executable, '-m', 'vizzy_runtime.cli', 'run', 'vizzy_gaze', 'gaze_controller']
    if ros_args:
        cmd += ['--ros-args', *ros_args]
    # SIGINT at its default in the child whatever the caller ignores (a shell's background job)
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=dict(os.environ, PYTHONUNBUFFERED='1'),
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _lines(proc: subprocess.Popen[str]) -> queue.Queue[str]:
    lines: queue.Queue[str] = queue.Queue()

    def pump() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.put(line)
        lines.put('')  # end of output

    threading.Thread(target=pump, daemon=True).start()
    return lines


def _publishes_gaze_state(deadline: float) -> bool:
    """Whether a /gaze/state arrives here before the deadline (the node under test spins)."""
    from vizzy_runtime.ros import Context, Node, SingleThreadedExecutor, message
    from vizzy_runtime.testing import wait_until

    context = Context()
    context.init()
    try:
        node = Node('gaze_state_probe', context=context)
        got: list[object] = []
        node.create_subscription(message('active_vision_msgs/msg/GazeState'), '/gaze/state',
                                 got.append, 10)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        ok = wait_until(lambda: bool(got), max(1.0, deadline - time.monotonic()), executor)
        executor.shutdown()
        node.destroy_node()
        return ok
    finally:
        context.try_shutdown()


def test_repeated_sigint_during_clean_up_exits_cleanly() -> None:
    proc = _node()
    lines = _lines(proc)
    seen: list[str] = []
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while not any('gaze controller:' in line for line in seen):
        try:
            seen.append(lines.get(timeout=max(0.1, deadline - time.monotonic())))
        except queue.Empty:
            proc.kill()
            pytest.fail(f'no start-up line within {STARTUP_TIMEOUT} s: {"".join(seen)[-2000:]}')
        assert seen[-1] or proc.poll() is None, f'the node ended early: {"".join(seen)[-2000:]}'
    # Spinning, not just built: the start-up line is printed before rcl sends it to /rosout, and
    # a signal in between makes rcl print that the rosout publisher's context is invalid.
    assert _publishes_gaze_state(deadline), f'no /gaze/state: {"".join(seen)[-2000:]}'
    for gap in (0.05, 0.05, 0.0):     # a terminal's Ctrl-C, launch's SIGINT, one more
        proc.send_signal(signal.SIGINT)
        time.sleep(gap)
    code = proc.wait(scaled(60))
    rest = ''.join(iter(lambda: lines.get(timeout=scaled(10)), ''))
    out = ''.join(seen) + rest
    assert code == 0, f'exit {code}: {out[-3000:]}'
    assert 'Traceback' not in out and 'KeyboardInterrupt' not in out, out[-3000:]
    assert 'context is invalid' not in out, out[-3000:]


@pytest.mark.parametrize('rule, names', [
    ('control_rate_hz:=abc', ('control_rate_hz',)),     # wrong type
    ('control_rate_hz:=-5.0', ('control_rate_hz',)),    # outside the descriptor's range
])
def test_a_bad_start_up_parameter_is_one_line_and_exit_2(rule: str, names: tuple[str, ...]) -> None:
    proc = _node('-p', rule)
    out, _ = proc.communicate(timeout=STARTUP_TIMEOUT)
    lines = [line for line in out.splitlines() if line.strip()]
    assert proc.returncode == 2, out[-3000:]
    assert 'Traceback' not in out, out[-3000:]
    assert len(lines) == 1, out[-3000:]
    assert 'gaze_controller' in lines[0] and all(n in lines[0] for n in names), lines[0]


def test_a_node_the_host_cannot_run_is_one_line_and_exit_1(tmp_path) -> None:
    # what the sim does when there is no OpenGL: main_for(..., cannot_start=(RendererUnavailable,))
    script = tmp_path / 'no_gl_node.py'
    script.write_text(
        'from vizzy_runtime.node_tools import main_for\n'
        'class RendererUnavailable(RuntimeError):\n    pass\n'
        'def make():\n    raise RendererUnavailable("no OpenGL backend (tried egl, osmesa)")\n'
        'main_for(make, cannot_start=(RendererUnavailable,))()\n')
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=STARTUP_TIMEOUT)
    assert proc.returncode == 1, proc.stderr[-3000:]
    assert proc.stderr.strip().splitlines() == [
        '[no_gl_node.py] cannot start: no OpenGL backend (tried egl, osmesa)'], proc.stderr[-3000:]
