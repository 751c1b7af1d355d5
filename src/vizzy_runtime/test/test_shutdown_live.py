"""Shutting a node down while its threads still publish, as the real rclpy revealed it: the first
SIGINT shuts the context down before spin returns (rclpy's signal handler; the bundled runtime
does the same), so a worker or a callback may be publishing right then. That must end quietly
(publish_from_thread, guarded, LatestWorker), destroy_node() must not wait long for a busy worker,
and the second SIGINT that `ros2 launch` plus a terminal's Ctrl-C deliver must not interrupt the
clean-up (node_tools.run).

Marked live: runs on the bundled runtime and on the real rclpy (scripts/test_ros.sh).
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time

import pytest

from vizzy_runtime.node_tools import LatestWorker, guarded, publish_from_thread
from vizzy_runtime.ros import ExternalShutdownException, Node, message
from vizzy_runtime.testing import scaled, wait_until

pytestmark = pytest.mark.live

String = message('std_msgs/msg/String')


class GatedWorkerNode(Node):
    """A node whose worker, once started on an item, publishes when the test opens the gate."""

    def __init__(self, name: str, context, close_timeout: float | None = None) -> None:
        super().__init__(name, context=context)
        self.pub = self.create_publisher(String, f'/{name}', 10)
        self.started, self.gate = threading.Event(), threading.Event()
        self.published: list[int] = []
        self.close_timeout = close_timeout
        self.worker = LatestWorker(name, guarded(self, 'worker failed', self.work))

    def work(self, item: int) -> None:
        self.started.set()
        self.gate.wait(scaled(10.0))
        publish_from_thread(self, self.pub, String(data='late'))
        self.published.append(item)

    def destroy_node(self) -> None:
        self.worker.close(self.close_timeout)
        super().destroy_node()


def test_a_worker_publishing_after_the_context_went_down_ends_quietly(context, capfd):
    node = GatedWorkerNode('shutdown_race_worker', context)
    try:
        node.worker.put(1)
        assert node.started.wait(scaled(10.0))
        context.shutdown()          # what the first Ctrl-C does, the worker still busy
        node.gate.set()
        assert node.worker.close(scaled(5.0)), 'the worker thread did not end'
        assert node.published == []
        err = capfd.readouterr().err
        assert 'worker failed' not in err and 'RCLError' not in err
    finally:
        node.gate.set()
        node.destroy_node()


def test_a_guarded_callback_publishing_after_the_context_went_down_ends_spin_quietly(
        context, capfd):
    node = Node('shutdown_race_callback', context=context)
    try:
        pub = node.create_publisher(String, '/shutdown_race_callback', 10)
        tick = guarded(node, 'tick failed', lambda: pub.publish(String(data='tick')))
        tick()                      # up: published
        context.shutdown()
        with pytest.raises(ExternalShutdownException):   # ends spin, as a signal does
            tick()
        assert 'tick failed' not in capfd.readouterr().err
    finally:
        node.destroy_node()


def test_destroy_node_waits_for_a_busy_worker_only_so_long(context, capfd):
    node = GatedWorkerNode('shutdown_busy_worker', context, close_timeout=0.3)
    try:
        node.worker.put(1)
        assert node.started.wait(scaled(10.0))
        node.destroy_node()         # the handle is still in flight, blocked on the gate
        # destroy_node returned although the handle cannot finish: the wait was bounded
        assert node.worker._thread.is_alive() and node.published == []
        node.gate.set()             # it finishes after destroy_node: its publish is dropped
        assert wait_until(lambda: not node.worker._thread.is_alive(), scaled(5.0))
        assert node.published == []
        assert 'worker failed' not in capfd.readouterr().err
    finally:
        node.gate.set()


CHURN = r'''
import time
from vizzy_runtime.node_tools import LatestWorker, guarded, publish_from_thread, run
from vizzy_runtime.ros import Node, message

String = message('std_msgs/msg/String')


class Churn(Node):
    """Publishes flat out from a timer and from a worker; slow to destroy."""

    def __init__(self):
        super().__init__('shutdown_churn')
        self.pub = self.create_publisher(String, 'shutdown_churn', 10)
        self.ticks = 0
        self.worker = LatestWorker('churn', guarded(self, 'worker failed', self.work))
        self.create_timer(0.002, guarded(self, 'timer failed', self.tick))

    def tick(self):
        self.ticks += 1
        self.pub.publish(String(data='tick'))
        self.worker.put(self.ticks)
        if self.ticks == 20:
            print('ready', flush=True)

    def work(self, item):
        end = time.monotonic() + 0.05
        while time.monotonic() < end:
            publish_from_thread(self, self.pub, String(data='work'))

    def destroy_node(self):
        self.worker.close()
        time.sleep(0.4)             # a clean-up that takes a while: a second SIGINT lands here
        print('destroyed', flush=True)
        super().destroy_node()


run(Churn, [])
print('clean exit', flush=True)
'''


def _default_signals() -> None:
    for sig in (signal.SIGINT, signal.SIGTERM):   # as a terminal's process has them
        signal.signal(sig, signal.SIG_DFL)


@pytest.mark.slow
@pytest.mark.parametrize('gap_s', [0.0, 0.1, 0.25])
def test_two_sigints_end_a_busy_node_cleanly(tmp_path, gap_s):
    script = tmp_path / 'churn.py'
    script.write_text(CHURN)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_default_signals)
    try:
        assert proc.stdout.readline().strip() == 'ready'
        time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        time.sleep(gap_s)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=scaled(30))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert out.split() == ['destroyed', 'clean', 'exit'], (out, err)
    for problem in ('Traceback', 'KeyboardInterrupt', 'RCLError', '[ERROR]', 'Failed to publish'):
        assert problem not in err, err
