"""A node run by node_tools.run() survives a /clock sample with a negative time, on both runtimes:
the bundled runtime refuses the sample; the real rclpy's TimeSource raises from its callback and
run() logs the fault and spins on. The node's clock then follows the next valid sample."""

from __future__ import annotations

import subprocess
import sys

import pytest

from vizzy_runtime.testing import scaled

pytestmark = [pytest.mark.live, pytest.mark.slow]

SCRIPT = r'''
import os, signal, threading, time
from vizzy_runtime import node_tools
from vizzy_runtime.ros import Node, Parameter, message

Clock = message('rosgraph_msgs/msg/Clock')

def factory():
    node = Node('clock_fault_subject', parameter_overrides=[Parameter('use_sim_time', value=True)])
    source = Node('clock_fault_source', context=node.context)
    pub = source.create_publisher(Clock, '/clock', 10)

    def feed():
        deadline = time.monotonic() + 30
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        junk = Clock()
        junk.clock.sec = -1
        for _ in range(3):
            pub.publish(junk)
            time.sleep(0.2)
        good = Clock()
        good.clock.sec = 42
        while node.get_clock().now().nanoseconds != 42_000_000_000 and time.monotonic() < deadline:
            pub.publish(good)
            time.sleep(0.1)
        print('clock', node.get_clock().now().nanoseconds, flush=True)
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=feed, daemon=True).start()
    return node

node_tools.run(factory, [])
print('stopped cleanly', flush=True)
'''


def test_a_negative_clock_sample_does_not_end_the_node():
    proc = subprocess.Popen([sys.executable, '-c', SCRIPT], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        stdout, stderr = proc.communicate(timeout=scaled(120))
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, stderr = proc.communicate()
        raise AssertionError(f'the node did not stop:\n{stdout}\n{stderr[-3000:]}') from None
    assert proc.returncode == 0, stdout + stderr[-3000:]
    assert 'clock 42000000000' in stdout and 'stopped cleanly' in stdout, stdout + stderr
    assert 'Traceback' not in stderr, stderr
