"""The bundled runtime's CPU cost per received message and per timer tick (issue 27).

This process publishes what the graph's sim sends every node, at the graph's rates (sim time =
wall time since start): /clock at 100 Hz, /joint_states at 50 Hz, /tf at 65 Hz (50 Hz with the
joints and 15 Hz at the images' stamps; the head's 5 joint transforms each, as the sim builds
them) and /tf_static once (latched). Meanwhile it runs, each in a process of its own, nodes that
only receive:

- ``idle``: a node that spins and receives nothing (the baseline every other one is taken from);
- ``clock``: use_sim_time (the node follows /clock);
- ``tf``: a TransformListener (/tf and /tf_static), wall time;
- ``joint_states``: a subscription to /joint_states whose callback does nothing;
- ``tf_reader``: use_sim_time and a TransformListener (what five nodes of the graph do);
- ``gaze_controller``: the real node with the graph's parameters (use_sim_time, 100 Hz control,
  10 Hz state, /tf, /joint_states).

and measures each one's CPU seconds (user + system, /proc) over --seconds. CPU per message
[ms] = (the role's CPU - idle's) / messages published in the window: load-independent, unlike
wall time. ``--variant NAME=SRC`` runs the roles from another source tree (its src/ folder, e.g.
a `git worktree` of an older commit) one after the other, so one run gives before and after.

    .venv/bin/python bench/runtime_messages.py [--seconds 30] [--variant before=/tmp/wt/src ...]

Prints, last, one JSON object: {variant: {cores: {role: cores}, cpu_ms_per_message: {clock,
tf, joint_states}, published_hz: {...}}}. Honours ROS_DOMAIN_ID (set one of your own).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

os.environ.setdefault('VIZZY_RUNTIME', 'bundled')

REPO = Path(__file__).resolve().parents[1]
ROLES = ('idle', 'clock', 'tf', 'joint_states', 'tf_reader', 'gaze_controller')
RATES = {'clock': 100.0, 'joint_states': 50.0, 'tf_images': 15.0}
READY = 'RUNTIME_MESSAGES_READY'


# --- the roles (child processes) ----------------------------------------------------------------

def run_role(role: str, ros_args: list[str]) -> None:
    from vizzy_runtime.node_tools import run
    from vizzy_runtime.ros import Node, message, qos_profile_sensor_data
    from vizzy_runtime.tf import TransformBuffer, TransformListener

    def factory() -> Any:
        if role == 'gaze_controller':
            from vizzy_gaze.gaze_controller_node import GazeControllerNode
            node = GazeControllerNode()
        else:
            node = Node(f'rt_probe_{role}')
            if role in ('tf', 'tf_reader'):
                node.tf_buffer = TransformBuffer()
                node.tf_listener = TransformListener(node.tf_buffer, node)
            if role == 'joint_states':
                node.sub = node.create_subscription(message('sensor_msgs/msg/JointState'),
                                                    'joint_states', lambda _m: None,
                                                    qos_profile_sensor_data)
        print(READY, flush=True)
        return node

    run(factory, ['--ros-args', *ros_args] if ros_args else None)


# --- the publisher (this process) ---------------------------------------------------------------

class Publisher:
    """/clock, /joint_states, /tf and /tf_static at the graph's rates, in a thread."""

    def __init__(self) -> None:
        from vizzy_runtime.convert import stamp_msg
        from vizzy_runtime.ros import Node, message, qos_profile_latched, rclpy
        from vizzy_sim_bridge.messages import float_seq, transform_messages
        from vizzy_vision import kinematics

        rclpy.init()
        self.node = Node('rt_probe_publisher')
        self._Clock = message('rosgraph_msgs/msg/Clock')
        self._JointState = message('sensor_msgs/msg/JointState')
        self._TFMessage = message('tf2_msgs/msg/TFMessage')
        self._stamp, self._float_seq, self._transforms = stamp_msg, float_seq, transform_messages
        self._kin = kinematics
        self.clock = self.node.create_publisher(self._Clock, '/clock', 10)
        self.joints = self.node.create_publisher(self._JointState, '/joint_states', 10)
        self.tf = self.node.create_publisher(self._TFMessage, '/tf', 100)
        static = self.node.create_publisher(self._TFMessage, '/tf_static', qos_profile_latched)
        static.publish(self._TFMessage(transforms=transform_messages(
            [kinematics.world_transform(), *kinematics.static_transforms()], stamp_msg(0.0))))
        self.counts = {'clock': 0, 'joint_states': 0, 'tf': 0}
        self._stop = threading.Event()
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _send_tf(self, t: float, joints: bool) -> None:
        pos = [0.1 * math.sin(t + i) for i in range(len(self._kin.JOINT_NAMES))]
        stamp = self._stamp(t)
        if joints:
            msg = self._JointState(name=list(self._kin.JOINT_NAMES))
            msg.header.stamp = stamp
            msg.position = self._float_seq(pos)
            msg.velocity = self._float_seq([0.0] * len(pos))
            msg.effort = self._float_seq([0.0] * len(pos))
            self.joints.publish(msg)
            self.counts['joint_states'] += 1
        self.tf.publish(self._TFMessage(transforms=self._transforms(
            self._kin.joint_transforms(pos), stamp)))
        self.counts['tf'] += 1

    def _loop(self) -> None:
        # absolute schedules: each stream keeps its rate whatever a publish costs
        next_at = {name: self._t0 for name in RATES}
        while not self._stop.is_set():
            name = min(next_at, key=next_at.__getitem__)
            delay = next_at[name] - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)
            t = next_at[name] - self._t0 + 1e-4       # sim time; never 0 (uninitialized)
            next_at[name] += 1.0 / RATES[name]
            if name == 'clock':
                self.clock.publish(self._Clock(clock=self._stamp(t)))
                self.counts['clock'] += 1
            else:
                self._send_tf(t, joints=name == 'joint_states')

    def close(self) -> None:
        from vizzy_runtime.ros import rclpy
        self._stop.set()
        self._thread.join()
        self.node.destroy_node()
        rclpy.try_shutdown()


def _cpu(pid: int) -> float:
    from vizzy_runtime.lockstep import process_cpu_seconds
    value = process_cpu_seconds(pid)
    if value is None:
        raise RuntimeError(f'process {pid} ended during the window')
    return value


def measure(pub: Publisher, name: str, src: str | None, seconds: float,
            warmup: float) -> dict[str, Any]:
    env = dict(os.environ)
    if src:
        env['PYTHONPATH'] = os.pathsep.join(
            str(p) for p in sorted(Path(src).iterdir()) if (p / 'setup.py').exists()
            or (p / 'pyproject.toml').exists())
    gaze_params = str(REPO / 'src' / 'vizzy_gaze' / 'config' / 'gaze_controller.yaml')
    args = {
        'idle': [], 'clock': ['-p', 'use_sim_time:=true'], 'tf': [], 'joint_states': [],
        'tf_reader': ['-p', 'use_sim_time:=true'],
        'gaze_controller': ['-p', 'use_sim_time:=true', '--params-file', gaze_params],
    }
    procs = {role: subprocess.Popen(
        [sys.executable, __file__, '--role', role, *args[role]], env=env, cwd=REPO,
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True) for role in ROLES}
    try:
        deadline = time.monotonic() + 120.0
        for role, proc in procs.items():
            assert proc.stdout is not None
            while time.monotonic() < deadline:
                line = proc.stdout.readline()
                if not line:
                    raise RuntimeError(f'{name}: role {role} exited before it was ready')
                if line.strip() == READY:
                    break
        time.sleep(warmup)                   # discovery, the latched /tf_static, first imports
        counts0, cpu0 = dict(pub.counts), {r: _cpu(p.pid) for r, p in procs.items()}
        t0 = time.monotonic()
        time.sleep(seconds)
        counts1, cpu1 = dict(pub.counts), {r: _cpu(p.pid) for r, p in procs.items()}
        elapsed = time.monotonic() - t0
    finally:
        for proc in procs.values():
            proc.terminate()
        for proc in procs.values():
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
    cores = {r: (cpu1[r] - cpu0[r]) / elapsed for r in ROLES}
    sent = {k: counts1[k] - counts0[k] for k in counts1}
    per_msg = {kind: round(1e3 * (cores[kind] - cores['idle']) * elapsed / max(1, sent[kind]), 4)
               for kind in ('clock', 'tf', 'joint_states')}
    return {'cores': {r: round(c, 4) for r, c in cores.items()},
            'cpu_ms_per_message': per_msg,
            'published_hz': {k: round(v / elapsed, 1) for k, v in sent.items()},
            'window_s': round(elapsed, 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=30.0)
    parser.add_argument('--warmup', type=float, default=5.0)
    parser.add_argument('--variant', action='append', default=[],
                        help='NAME=SRC: run the roles from SRC (a source tree\'s src/ folder)')
    parser.add_argument('--role', choices=ROLES, help=argparse.SUPPRESS)
    args, ros_args = parser.parse_known_args()
    if args.role:
        run_role(args.role, [a for a in ros_args if a != '--ros-args'])
        return
    variants: list[tuple[str, str | None]] = []
    for spec in args.variant:
        name, sep, src = spec.partition('=')
        if not sep or not Path(src).is_dir():
            parser.error(f'--variant {spec!r}: expected NAME=SRC with SRC a folder')
        variants.append((name, src))
    variants = variants or [('this', None)]
    pub = Publisher()
    results = {}
    try:
        for name, src in variants:
            results[name] = measure(pub, name, src, args.seconds, args.warmup)
            print(name, json.dumps(results[name]), file=sys.stderr, flush=True)
    finally:
        pub.close()
    print(json.dumps(results))


if __name__ == '__main__':
    main()
