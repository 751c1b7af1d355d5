"""Transport benchmark: a 640x480 rgb8 sensor_msgs/Image between two processes.

Through the runtime (rclpy API: message objects, our CDR codec, Cyclone DDS) and, for
comparison, as raw pre-serialized bytes through cyclonedds without our layer. Reliable,
keep-last 5, loopback. Two runs per path: the publisher flat out (image_hz: what the subscriber
process receives per second), then paced at PACED_HZ, the rate target (latency_ms_p50: one-way,
header stamp to receive time; flat out, latency only measures the 5-deep queue and is reported too).

Across vendors (image_hz_<publisher>_to_<subscriber>, delivered_fraction_<...>): the same image from
a publisher process to a subscriber process, each on the bundled runtime (Cyclone DDS) or on the
real rclpy (.venv-ros: rmw_fastrtps_cpp, with the real-rclpy tier's environment,
testing.real_rclpy_env()): all four pairs under the same conditions, sensor-data QoS (best effort,
keep last 5, as camera images are published), the publisher flat out for DURATION_S. Skipped, with
the reason in vendor_pairs_skipped, where .venv-ros is missing.

    .venv/bin/python bench/transport.py           # last line: one JSON object
"""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

DURATION_S = 4.0
PACED_HZ = 300.0
W, H = 640, 480
REPO = Path(__file__).resolve().parents[1]
VENDOR_PAIRS = (('bundled', 'bundled'), ('real', 'real'), ('bundled', 'real'), ('real', 'bundled'))
VENDOR_TOPIC = '/bench/vendor_image'


def _time_it(fn, repeat: int = 50) -> float:
    fn()
    best = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best.append(time.perf_counter() - t0)
    return float(np.median(best) * 1e3)


def codec_figures() -> dict[str, float]:
    from vizzy_runtime import msgs
    from vizzy_runtime.convert import numpy_to_image
    frame = np.random.default_rng(0).integers(0, 255, (H, W, 3), dtype=np.uint8)
    msg = numpy_to_image(frame, 'rgb8')
    raw = bytes(msgs.serialize(msg))
    dst = np.empty(frame.size, np.uint8)
    return {
        'serialize_ms': _time_it(lambda: msgs.serialize(msg)),
        'deserialize_ms': _time_it(lambda: msgs.deserialize(raw, 'sensor_msgs/msg/Image')),
        'memcpy_ms': _time_it(lambda: np.copyto(dst, frame.reshape(-1))),
    }


# --- subscriber side (child process) -----------------------------------------------------------

def run_subscriber(mode: str) -> None:
    from vizzy_runtime import dds
    stamps: list[tuple[int, int]] = []
    if mode == 'runtime':
        from vizzy_runtime.ros import Node, QoSProfile, message, rclpy
        rclpy.init(args=[])
        node = Node('bench_sub')
        Image = message('sensor_msgs/msg/Image')

        def on_image(msg) -> None:
            now = time.time_ns()
            stamps.append((now, msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec))
        _sub = node.create_subscription(Image, '/bench/image', on_image, QoSProfile(depth=5))
        print('ready', flush=True)
        start = time.monotonic()
        from vizzy_runtime.rclpy_compat import get_global_executor
        ex = get_global_executor()
        ex.add_node(node)
        while time.monotonic() - start < DURATION_S + 20 \
                and not (stamps and time.time_ns() - stamps[-1][0] > 1e9):
            ex.spin_once(0.1)
    else:
        reader = dds.RawReader('/bench/raw', 'sensor_msgs/msg/Image', dds.QoS(depth=5))
        print('ready', flush=True)
        start = time.monotonic()
        while time.monotonic() - start < DURATION_S + 20 \
                and not (stamps and time.time_ns() - stamps[-1][0] > 1e9):
            for raw, _ts in reader.take(16):
                now = time.time_ns()
                sec, nsec = np.frombuffer(raw, dtype='<i4', count=2, offset=4)  # header.stamp
                stamps.append((now, int(sec) * 1_000_000_000 + int(np.uint32(nsec))))
            time.sleep(0.0002)
    recv = np.array(stamps, dtype=np.int64)
    print(json.dumps({'received': len(stamps),
                      'span_s': float((recv[-1, 0] - recv[0, 0]) / 1e9) if len(stamps) > 1 else 0.0,
                      'latency_ms_p50': (float(np.median((recv[:, 0] - recv[:, 1]) / 1e6))
                                         if len(stamps) else None)}),
          flush=True)


# --- publisher side ----------------------------------------------------------------------------

def _pace(start: float, sent: int, rate_hz: float | None) -> None:
    if rate_hz:
        delay = start + sent / rate_hz - time.monotonic()
        if delay > 0:
            time.sleep(delay)


def run_publisher(mode: str, rate_hz: float | None = None) -> dict[str, float]:
    from vizzy_runtime import dds, msgs
    from vizzy_runtime.convert import numpy_to_image
    child = subprocess.Popen([sys.executable, __file__, '--sub', mode], stdout=subprocess.PIPE,
                             text=True, env={**os.environ})
    assert child.stdout is not None
    assert child.stdout.readline().strip() == 'ready'
    frame = np.random.default_rng(1).integers(0, 255, (H, W, 3), dtype=np.uint8)
    sent = 0
    if mode == 'runtime':
        from vizzy_runtime.ros import Node, QoSProfile, rclpy
        if not rclpy.ok():
            rclpy.init(args=[])
        node = Node('bench_pub')
        Image = msgs.get_message('sensor_msgs/msg/Image')
        pub = node.create_publisher(Image, '/bench/image', QoSProfile(depth=5))
        pub.wait_for_subscribers(1, 20)
        msg = numpy_to_image(frame, 'rgb8')
        start = time.monotonic()
        end = start + DURATION_S
        while time.monotonic() < end:
            _pace(start, sent, rate_hz)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(time.time_ns(), 1_000_000_000)
            pub.publish(msg)
            sent += 1
        node.destroy_node()
    else:
        writer = dds.RawWriter('/bench/raw', 'sensor_msgs/msg/Image', dds.QoS(depth=5))
        deadline = time.monotonic() + 20
        while writer.matched_count() < 1 and time.monotonic() < deadline:
            time.sleep(0.005)
        raw = bytearray(msgs.serialize(numpy_to_image(frame, 'rgb8')))
        start = time.monotonic()
        end = start + DURATION_S
        while time.monotonic() < end:
            _pace(start, sent, rate_hz)
            sec, nsec = divmod(time.time_ns(), 1_000_000_000)
            raw[4:12] = np.array([sec, nsec], dtype='<u4').tobytes()
            writer.write(bytes(raw))
            sent += 1
    out, _ = child.communicate(timeout=60)
    result = json.loads(out.strip().splitlines()[-1])
    result['sent'] = sent
    return result


# --- across vendors: bundled runtime and real rclpy, each side its own process ------------------

def real_python() -> Path | None:
    """.venv-ros's interpreter (the real rclpy), or None where setup did not create it."""
    python = REPO / '.venv-ros' / 'bin' / 'python'
    return python if python.is_file() and os.access(python, os.X_OK) else None


def _vendor_command(runtime: str, role: str) -> tuple[list[str], dict[str, str]]:
    if runtime == 'real':
        from vizzy_runtime.testing import real_rclpy_env
        return [str(real_python()), __file__, '--vendor', role], real_rclpy_env()
    return [sys.executable, __file__, '--vendor', role], {**os.environ, 'VIZZY_RUNTIME': 'bundled'}


def run_vendor_subscriber() -> None:
    """Child, on either runtime: counts images until a line arrives on stdin."""
    from vizzy_runtime.ros import Node, message, qos_profile_sensor_data, rclpy
    rclpy.init(args=[])
    node = Node('bench_vendor_sub')
    times: list[float] = []
    node.create_subscription(message('sensor_msgs/msg/Image'), VENDOR_TOPIC,
                             lambda _msg: times.append(time.monotonic()), qos_profile_sensor_data)
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.readline(), stop.set()), daemon=True).start()
    print('ready', flush=True)
    deadline = time.monotonic() + DURATION_S + 90
    while not stop.is_set() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    print(json.dumps({'received': len(times),
                      'span_s': times[-1] - times[0] if len(times) > 1 else 0.0}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def run_vendor_publisher() -> None:
    """Child, on either runtime: once the subscriber matched, publishes flat out for DURATION_S."""
    from vizzy_runtime.convert import numpy_to_image
    from vizzy_runtime.ros import Node, qos_profile_sensor_data, rclpy
    rclpy.init(args=[])
    node = Node('bench_vendor_pub')
    msg = numpy_to_image(np.random.default_rng(1).integers(0, 255, (H, W, 3), dtype=np.uint8),
                         'rgb8')
    pub = node.create_publisher(type(msg), VENDOR_TOPIC, qos_profile_sensor_data)
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.5)  # the subscriber's side of the match
    sent = 0
    start = time.monotonic()
    while time.monotonic() - start < DURATION_S:
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(time.time_ns(), 1_000_000_000)
        pub.publish(msg)
        sent += 1
    time.sleep(0.5)  # the last images are still being read
    print(json.dumps({'sent': sent}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def run_vendor_pair(pub_runtime: str, sub_runtime: str) -> dict[str, float]:
    cmd, env = _vendor_command(sub_runtime, 'sub')
    child = subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None
        for line in child.stdout:  # Fast DDS may log to stdout first
            if line.strip() == 'ready':
                break
        cmd, env = _vendor_command(pub_runtime, 'pub')
        out = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True, check=True,
                             timeout=DURATION_S + 90)
        sent = json.loads(out.stdout.strip().splitlines()[-1])['sent']
        stdout, _ = child.communicate('stop\n', timeout=60)
        got = json.loads(stdout.strip().splitlines()[-1])
    finally:
        if child.poll() is None:
            child.kill()
    return {'sent': sent, 'received': got['received'],
            'image_hz': got['received'] / max(got['span_s'], 1e-9) if got['received'] > 1 else 0.0}


def vendor_figures() -> dict[str, object]:
    """image_hz_<pub>_to_<sub> and delivered_fraction_<pub>_to_<sub> for the four pairs."""
    if real_python() is None:
        skipped = REPO / '.venv-ros.skipped'
        reason = (skipped.read_text().strip() if skipped.is_file()
                  else 'run `make setup` to create it')
        return {'vendor_pairs_skipped': f'no .venv-ros (the real rclpy): {reason}'}
    figures: dict[str, object] = {
        'vendor_pairs_qos': 'sensor_data (best effort, keep last 5), flat out'}
    for pub_runtime, sub_runtime in VENDOR_PAIRS:
        pair = run_vendor_pair(pub_runtime, sub_runtime)
        figures[f'image_hz_{pub_runtime}_to_{sub_runtime}'] = round(pair['image_hz'], 1)
        figures[f'delivered_fraction_{pub_runtime}_to_{sub_runtime}'] = round(
            pair['received'] / max(pair['sent'], 1), 3)
    return figures


def main() -> None:
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))
    if len(sys.argv) == 3 and sys.argv[1] == '--vendor':   # a child of run_vendor_pair
        run_vendor_subscriber() if sys.argv[2] == 'sub' else run_vendor_publisher()
        return
    os.environ['VIZZY_RUNTIME'] = 'bundled'
    if len(sys.argv) == 3 and sys.argv[1] == '--sub':
        run_subscriber(sys.argv[2])
        return
    figures = codec_figures()
    ours = run_publisher('runtime')
    ours_paced = run_publisher('runtime', PACED_HZ)
    raw = run_publisher('raw')
    raw_paced = run_publisher('raw', PACED_HZ)
    summary = {
        'image_hz': round(ours['received'] / max(ours['span_s'], 1e-9), 1),
        'latency_ms_p50': round(ours_paced['latency_ms_p50'], 3),
        'paced_hz': PACED_HZ,
        'paced_delivered_fraction': round(ours_paced['received'] / max(ours_paced['sent'], 1), 3),
        'latency_ms_p50_flat_out': round(ours['latency_ms_p50'], 3),
        'serialize_ms': round(figures['serialize_ms'], 3),
        'deserialize_ms': round(figures['deserialize_ms'], 3),
        'memcpy_ms': round(figures['memcpy_ms'], 3),
        'raw_cyclonedds_image_hz': round(raw['received'] / max(raw['span_s'], 1e-9), 1),
        'raw_cyclonedds_latency_ms_p50': round(raw_paced['latency_ms_p50'], 3),
        'sent': ours['sent'], 'received': ours['received'],
    }
    summary.update(vendor_figures())
    print(f"runtime: {summary['image_hz']} Hz, p50 {summary['latency_ms_p50']} ms; raw cyclonedds: "
          f"{summary['raw_cyclonedds_image_hz']} Hz, "
          f"p50 {summary['raw_cyclonedds_latency_ms_p50']} ms",
          file=sys.stderr, flush=True)
    if 'image_hz_bundled_to_real' in summary:
        print('VGA images/s, sensor-data QoS: ' + ', '.join(
            f"{p}->{s} {summary[f'image_hz_{p}_to_{s}']}" for p, s in VENDOR_PAIRS),
            file=sys.stderr, flush=True)
    print(json.dumps(summary), flush=True)


if __name__ == '__main__':
    main()
