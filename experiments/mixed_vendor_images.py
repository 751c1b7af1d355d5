"""Mixed-vendor image transport: a 640x480 rgb8 sensor_msgs/Image from one publisher process to a
bundled-runtime (Cyclone DDS) subscriber and a real-rclpy (rmw_fastrtps_cpp) subscriber at once.

    ROS_DOMAIN_ID=122 .venv/bin/python experiments/mixed_vendor_images.py \
        [--pub bundled|ros] [--qos be|rel] [--rate HZ (0: flat out)] [--duration S] [--subs ...]

XV_NO_PROFILE=1: the real-rclpy processes without the tier's Fast DDS profile (the "before").
XV_CYCLONE_SUB, XV_STRACE: see _patch_cyclone() and _traced().

Prints per subscriber what it received of what was sent (last line: one JSON object). The
publisher and each subscriber are separate processes: bundled on .venv's python, real on
.venv-ros's (VIZZY_RUNTIME=ros).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TOPIC = '/xv/image'
W, H = 640, 480


def _python(runtime: str) -> tuple[str, dict[str, str]]:
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    env.pop('PYTHONPATH', None)
    if runtime == 'ros':
        if os.environ.get('XV_NO_PROFILE'):   # "before": Jazzy's LOCALHOST range, Fast DDS defaults
            env.update(VIZZY_RUNTIME='ros', ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
        else:                                 # the real-rclpy tier's environment (Fast DDS profile)
            from vizzy_runtime.testing import real_rclpy_env
            env = real_rclpy_env()
        return str(REPO / '.venv-ros' / 'bin' / 'python'), env
    env['VIZZY_RUNTIME'] = 'bundled'
    return str(REPO / '.venv' / 'bin' / 'python'), env


def _qos(kind: str):
    from vizzy_runtime.ros import QoSProfile, qos_profile_sensor_data
    return qos_profile_sensor_data if kind == 'be' else QoSProfile(depth=5)


def _spin_until(node, rclpy, stop, limit_s: float = 300.0) -> None:
    deadline = time.monotonic() + limit_s
    while not stop() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)


def _patch_cyclone() -> None:
    """Experiment knob: XV_CYCLONE_SUB='old=>new;old2=>new2' rewrites loopback_config()'s XML."""
    subs = os.environ.get('XV_CYCLONE_SUB')
    if not subs:
        return
    from vizzy_runtime import dds
    base = dds.loopback_config

    def patched() -> str:
        xml = base()
        for rule in subs.split(';'):
            old, new = rule.split('=>')
            assert old in xml, old
            xml = xml.replace(old, new)
        return xml
    dds.loopback_config = patched


def role_sub(qos: str) -> None:
    _patch_cyclone()
    from vizzy_runtime.ros import Node, message, rclpy
    rclpy.init(args=[])
    node = Node('xv_sub')
    count = [0]
    first_last = [0.0, 0.0]

    def on_image(msg) -> None:
        now = time.monotonic()
        if not count[0]:
            first_last[0] = now
        first_last[1] = now
        count[0] += 1
    node.create_subscription(message('sensor_msgs/msg/Image'), TOPIC, on_image, _qos(qos))
    print('ready', flush=True)
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.readline(), done.set()), daemon=True).start()
    _spin_until(node, rclpy, done.is_set)
    print(json.dumps({'received': count[0], 'span_s': first_last[1] - first_last[0]}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def role_pub(qos: str, rate: float, duration: float, subscribers: int) -> None:
    import numpy as np
    _patch_cyclone()
    from vizzy_runtime.convert import numpy_to_image
    from vizzy_runtime.ros import Node, rclpy
    rclpy.init(args=[])
    node = Node('xv_pub')
    frame = np.random.default_rng(1).integers(0, 255, (H, W, 3), dtype=np.uint8)
    msg = numpy_to_image(frame, 'rgb8')
    pub = node.create_publisher(type(msg), TOPIC, _qos(qos))
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() < subscribers and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    matched = pub.get_subscription_count()
    time.sleep(1.0)  # let the subscribers also see the writer
    sent = 0
    start = time.monotonic()
    while time.monotonic() - start < duration:
        if rate:
            delay = start + sent / rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(time.time_ns(), 1_000_000_000)
        pub.publish(msg)
        sent += 1
    elapsed = time.monotonic() - start
    time.sleep(1.0)  # drain
    print(json.dumps({'sent': sent, 'elapsed_s': elapsed, 'matched': matched}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def _traced(cmd: list[str], name: str) -> list[str]:
    """XV_STRACE=DIR: run under strace, logging every socket call to DIR/NAME.txt."""
    where = os.environ.get('XV_STRACE')
    if not where:
        return cmd
    return ['strace', '-f', '-qq', '-e', 'trace=bind,connect,sendto,sendmsg,sendmmsg,setsockopt',
            '-o', f'{where}/{name}.txt', *cmd]


def run(pub: str, qos: str, rate: float, duration: float, subs: tuple[str, ...] = ('bundled', 'ros')
        ) -> dict:
    children = {}
    for runtime in subs:
        python, env = _python(runtime)
        child = subprocess.Popen(_traced([python, __file__, '--role', 'sub', '--qos', qos],
                                         f'sub-{runtime}'), env=env,
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert child.stdout.readline().strip() == 'ready'
        children[runtime] = child
    try:
        return _run_pub(children, pub, qos, rate, duration, len(subs))
    finally:
        for child in children.values():
            if child.poll() is None:
                child.kill()


def _run_pub(children: dict, pub: str, qos: str, rate: float, duration: float, nsubs: int) -> dict:
    python, env = _python(pub)
    out = subprocess.run(_traced([python, __file__, '--role', 'pub', '--qos', qos,
                                  '--rate', str(rate), '--duration', str(duration),
                                  '--subscribers', str(nsubs)],
                                 f'pub-{pub}'),
                         env=env, stdout=subprocess.PIPE, text=True, timeout=duration + 90,
                         check=True)
    result = {'pub': pub, 'qos': qos, 'rate_hz': rate,
              **json.loads(out.stdout.strip().splitlines()[-1])}
    for runtime, child in children.items():
        stdout, _ = child.communicate('stop\n', timeout=30)
        got = json.loads(stdout.strip().splitlines()[-1])
        result[f'{runtime}_received'] = got['received']
        result[f'{runtime}_fraction'] = round(got['received'] / max(result['sent'], 1), 3)
    return result


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument('--role', choices=('run', 'pub', 'sub'), default='run')
    parser.add_argument('--pub', choices=('bundled', 'ros'), default='bundled')
    parser.add_argument('--qos', choices=('be', 'rel'), default='be')
    parser.add_argument('--rate', type=float, default=15.0)
    parser.add_argument('--duration', type=float, default=10.0)
    parser.add_argument('--subscribers', type=int, default=2)
    parser.add_argument('--subs', default='bundled,ros')
    args = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', '122')
    if args.role == 'sub':
        role_sub(args.qos)
    elif args.role == 'pub':
        role_pub(args.qos, args.rate, args.duration, args.subscribers)
    else:
        result = run(args.pub, args.qos, args.rate, args.duration, tuple(args.subs.split(',')))
        print(json.dumps(result), flush=True)


if __name__ == '__main__':
    main()
