"""Simulator benchmark: the `sim` node (MuJoCo head, tabletop scene) in its own process.

This process subscribes like any consumer would and measures, over WINDOW_S seconds:
  stereo_hz             left/right 640x480 rgb8 pairs received (both images of one stamp), with
                        the sim asked for 30 Hz (the robot cameras' rate; default config: 15 Hz)
  rgbd_hz               organized 640x480 x y z rgb clouds received (sim asked for RGBD_HZ)
  physics_hz            MuJoCo steps per wall second: sim time advance on /clock / timestep
  command_to_motion_ms  median over TRIALS of: a joint target published on
                        /vizzy/joint_commands -> the first /joint_states (100 Hz) showing the
                        joint 1 mrad (0.06 deg) away from where it was; includes DDS both ways
                        and up to one joint_states period (10 ms)
Also sim_cpu_percent (the sim process, of one core), sim_cpu_ms_per_pair (its CPU over the
stereo pairs received: physics, RGB-D and the rest included), the sim's peak sim_rss_mb and
sim_pss_mb over the window (/proc/<pid>/status, smaps_rollup; issue 27) and the machine's core
count.

    .venv/bin/python bench/sim.py [--scene tabletop] [--window 10] [--stereo-hz 30]
    # last line: one JSON object
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / 'src' / 'vizzy_sim_bridge' / 'config' / 'sim.yaml'
STEREO_HZ, RGBD_HZ, TIMESTEP = 30.0, 5.0, 0.002
TRIALS = 12
_RESULT: dict[str, object] = {}


def _cpu_seconds(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scene', default='tabletop')
    parser.add_argument('--window', type=float, default=10.0, help='measuring window [s]')
    parser.add_argument('--stereo-hz', type=float, default=STEREO_HZ,
                        help='stereo rate asked of the sim [Hz] (60: see what the machine gives)')
    ns = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))
    os.environ['VIZZY_RUNTIME'] = 'bundled'

    # the sim's output: shown only if it fails to come up
    with tempfile.TemporaryFile('w+') as log:
        sim = subprocess.Popen(
            [sys.executable, '-m', 'vizzy_sim_bridge.sim_node', '--ros-args', '--params-file',
             str(CONFIG), '-p', f'scene:={ns.scene}', '-p', f'rate_hz:={ns.stereo_hz}',
             '-p', f'rgbd_rate_hz:={RGBD_HZ}',
             '-p', 'initial_joint_positions:=[0.0, 0.2, 0.15, 0.0, 0.0]'],
            env=os.environ.copy(), stdout=log, stderr=subprocess.STDOUT)
        try:
            status = _measure(sim, ns)
        finally:
            sim.send_signal(signal.SIGINT)
            try:
                sim.wait(10)
            except subprocess.TimeoutExpired:
                sim.kill()
        if status:
            log.seek(0)
            print(log.read()[-3000:], file=sys.stderr)
        else:
            print(json.dumps(_RESULT), flush=True)   # the last line, after the sim has stopped
    return status


def _measure(sim: subprocess.Popen, ns: argparse.Namespace) -> int:
    from graph_budget import memory_mb  # bench/graph_budget.py's (RSS, PSS) reader

    from vizzy_runtime.ros import Node, message, qos_profile_sensor_data, rclpy
    from vizzy_runtime.testing import wait_until

    Image = message('sensor_msgs/msg/Image')
    PointCloud2 = message('sensor_msgs/msg/PointCloud2')
    Clock = message('rosgraph_msgs/msg/Clock')
    JointState = message('sensor_msgs/msg/JointState')
    rclpy.init(args=[])
    node = Node('bench_sim')
    stamps: dict[str, list[int]] = {'left': [], 'right': [], 'rgbd': []}
    clock: list[tuple[float, float]] = []
    joints: list[tuple[float, float]] = []   # (wall receive time, l_eye_joint)

    def keep(key: str):
        def cb(msg) -> None:
            stamps[key].append(msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec)
        return cb

    node.create_subscription(Image, '/vizzy/left/image_raw', keep('left'), qos_profile_sensor_data)
    node.create_subscription(Image, '/vizzy/right/image_raw', keep('right'),
                             qos_profile_sensor_data)
    node.create_subscription(PointCloud2, '/vizzy/rgbd/points', keep('rgbd'),
                             qos_profile_sensor_data)
    node.create_subscription(Clock, '/clock', lambda m: clock.append(
        (time.monotonic(), m.clock.sec + m.clock.nanosec * 1e-9)), 10)

    def on_joints(msg) -> None:
        joints.append((time.monotonic(), float(msg.position[list(msg.name).index('l_eye_joint')])))
    node.create_subscription(JointState, '/joint_states', on_joints, 100)
    commands = node.create_publisher(JointState, '/vizzy/joint_commands', 10)

    peak = {'rss': 0.0, 'pss': 0.0}

    def spin_for(seconds: float, memory: bool = False) -> None:
        end = time.monotonic() + seconds
        next_sample = 0.0
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.01)
            if memory and time.monotonic() >= next_sample:      # twice a second
                next_sample = time.monotonic() + 0.5
                sample = memory_mb(sim.pid)                     # None: the sim is gone
                if sample is not None:
                    peak['rss'], peak['pss'] = max(peak['rss'], sample[0]), max(peak['pss'],
                                                                                sample[1])

    print(f'bench/sim: starting the sim ({ns.scene}) ...', file=sys.stderr, flush=True)
    ok = wait_until(lambda: (rclpy.spin_once(node, timeout_sec=0.01) or True) and
                    len(stamps['left']) > 5 and len(stamps['rgbd']) > 1 and len(joints) > 5, 120.0)
    if not ok or sim.poll() is not None:
        print('bench/sim: the sim did not come up', file=sys.stderr)
        return 1
    spin_for(2.0)   # warm up
    for v in stamps.values():
        v.clear()
    clock.clear()
    cpu0, wall0 = _cpu_seconds(sim.pid), time.monotonic()
    print(f'bench/sim: measuring for {ns.window:g} s ...', file=sys.stderr, flush=True)
    spin_for(ns.window, memory=True)
    wall = time.monotonic() - wall0
    cpu = _cpu_seconds(sim.pid) - cpu0
    pairs = len(set(stamps['left']) & set(stamps['right']))
    stereo_hz = pairs / wall
    rgbd_hz = len(stamps['rgbd']) / wall
    (w0, s0), (w1, s1) = clock[0], clock[-1]
    physics_hz = (s1 - s0) / TIMESTEP / (w1 - w0)

    latencies = []
    target = 0.15
    for _trial in range(TRIALS):
        target = -target
        spin_for(0.3)                         # let the previous move settle
        start_q = joints[-1][1]
        n = len(joints)
        t0 = time.monotonic()
        commands.publish(JointState(name=['l_eye_joint'], position=[target]))
        moved = wait_until(
            lambda start_q=start_q, n=n: (rclpy.spin_once(node, timeout_sec=0.001) or True)
            and any(abs(q - start_q) > 1e-3 for _, q in joints[n:]), 5.0)
        if moved:
            t1 = next(t for t, q in joints[n:] if abs(q - start_q) > 1e-3)
            latencies.append((t1 - t0) * 1e3)
    node.destroy_node()
    rclpy.try_shutdown()
    result = {
        'stereo_hz': round(stereo_hz, 2),
        'rgbd_hz': round(rgbd_hz, 2),
        'physics_hz': round(physics_hz, 1),
        'command_to_motion_ms': round(float(np.median(latencies)), 2) if latencies else None,
        'command_to_motion_ms_max': round(float(np.max(latencies)), 2) if latencies else None,
        'requested_stereo_hz': ns.stereo_hz,
        'requested_rgbd_hz': RGBD_HZ,
        'sim_cpu_percent': round(100.0 * cpu / wall, 1),
        'sim_cpu_ms_per_pair': round(1e3 * cpu / pairs, 2) if pairs else None,
        'sim_rss_mb': round(peak['rss'], 1),
        'sim_pss_mb': round(peak['pss'], 1),
        'cpu_count': os.cpu_count(),
        'scene': ns.scene,
        'window_s': ns.window,
    }
    _RESULT.update(result)
    return 0


if __name__ == '__main__':
    sys.exit(main())
