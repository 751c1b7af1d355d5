"""Live view memory probe (issue 28 item 1): the live view's RSS while Foxglove clients that never
read are subscribed to a VGA image stream, and the image rate a normal client gets meanwhile.

A server process runs a LiveView (live_view.py), a publisher process sends 640x480 rgb8
sensor_msgs/Image at --hz through the bundled runtime (Cyclone DDS), and this process opens one
reading client (counts images) and N raw WebSocket clients (subprotocol foxglove.sdk.v1, a small
SO_RCVBUF) that subscribe to the image channel and then never read. The server's RSS (/proc) is
sampled every second for --duration seconds, then the slow clients close and it is sampled again.
Prints, last, one JSON object: per N, rss_mb_before (the reading client connected, no slow one
yet), rss_mb_peak, rss_mb_end (after `seconds`; a run ends early past --max-rss-mb),
rss_mb_after_leave, fast_client_hz (images/s the reading client got while the slow ones were
connected) and publish_hz (what the publisher sent); with --rounds R, the slow clients come and go
R times against the same server and the peaks and after-leave figures of every round are listed.

    .venv/bin/python bench/live_view_memory.py [--clients 1,10] [--duration 40] [--hz 30]
                                               [--rounds 1]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ.setdefault('VIZZY_RUNTIME', 'bundled')
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'src/vizzy_runtime/test'))
from foxglove_client import RawClient  # noqa: E402

TOPIC = '/probe/image_raw'
TYPE = 'sensor_msgs/msg/Image'
SLOW_RCVBUF = 4096          # the kernel doubles it: 8 KiB, under 1 % of one image
AFTER_LEAVE_S = 5.0


# --- the two child processes ----------------------------------------------------------------------

def serve() -> None:
    from vizzy_runtime.live_view import LiveView
    view = LiveView(port=0)
    print(view.start(), flush=True)
    sys.stdin.readline()        # the probe closes stdin to stop us
    view.stop()


def publish(hz: float) -> None:
    import numpy as np

    from vizzy_runtime import dds, msgs
    from vizzy_runtime.convert import numpy_to_image
    frame = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    data = bytes(msgs.serialize(numpy_to_image(frame, 'rgb8'), TYPE))
    writer = dds.RawWriter(TOPIC, TYPE, dds.QoS(reliable=False, depth=5))  # sensor-data QoS
    stop = threading.Event()

    def wait_eof() -> None:
        sys.stdin.read()
        stop.set()
    threading.Thread(target=wait_eof, daemon=True).start()
    sent, start = 0, time.monotonic()
    print(len(data), flush=True)
    while not stop.is_set():
        writer.write(data)
        sent += 1
        stop.wait(max(0.0, start + sent / hz - time.monotonic()))
    print(json.dumps({'sent': sent, 'seconds': time.monotonic() - start}), flush=True)


# --- the clients -------------------------------------------------------------------------------

def count_images(client: RawClient, times: list[float], stop: threading.Event) -> None:
    """The fast client: read everything, note when each image arrives."""
    try:
        while not stop.is_set():
            opcode, payload = client.frame()
            if opcode == 2 and payload[:1] == b'\x01':
                times.append(time.monotonic())
            elif opcode == 1 and b'Unknown channel' in payload:
                # foxglove-sdk sends an advertisement before it records the channel as advertised
                # to that client: a subscription answering it at once can be refused; ask again
                client.send_text(client.subscribe_text)
    except OSError:
        pass


# --- the probe ----------------------------------------------------------------------------------

def rss_mb(pid: int) -> float:
    with open(f'/proc/{pid}/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024
    return float('nan')


def child(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, __file__, *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)


def slow_round(port: int, server_pid: int, n_slow: int, duration: float, max_rss_mb: float,
               times: list[float]) -> dict[str, float]:
    """N slow clients for `duration` seconds, then AFTER_LEAVE_S seconds after they left."""
    before = rss_mb(server_pid)
    slow = [RawClient(port, rcvbuf=SLOW_RCVBUF) for _ in range(n_slow)]
    for c in slow:
        c.subscribe(TOPIC)
    t0 = time.monotonic()
    samples = []
    while time.monotonic() - t0 < duration:
        time.sleep(1.0)
        samples.append(rss_mb(server_pid))
        if samples[-1] > max_rss_mb:  # protect the machine: the figure is already made
            break
    t1 = time.monotonic()
    got = sum(1 for t in times if t0 <= t <= t1)
    for c in slow:
        c.close()
    time.sleep(AFTER_LEAVE_S)
    return {'rss_mb_before': round(before, 1), 'rss_mb_peak': round(max(samples), 1),
            'rss_mb_end': round(samples[-1], 1), 'seconds': round(t1 - t0, 1),
            'rss_mb_after_leave': round(rss_mb(server_pid), 1),
            'fast_client_hz': round(got / (t1 - t0), 1)}


def run(n_slow: int, duration: float, hz: float, max_rss_mb: float,
        rounds: int) -> dict[str, Any]:
    server = child('--serve')
    port = int(server.stdout.readline())  # type: ignore[union-attr]
    publisher = child('--publish', str(hz))
    image_bytes = int(publisher.stdout.readline())  # type: ignore[union-attr]
    fast = RawClient(port)
    fast.subscribe(TOPIC)
    times: list[float] = []
    stop = threading.Event()
    threading.Thread(target=count_images, args=(fast, times, stop), daemon=True).start()
    deadline = time.monotonic() + 60
    while len(times) < 10 and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(2)
    results = [slow_round(port, server.pid, n_slow, duration, max_rss_mb, times)
               for _ in range(rounds)]
    stop.set()
    fast.close()
    publisher.stdin.close()  # type: ignore[union-attr]
    pub = json.loads(publisher.stdout.readline())  # type: ignore[union-attr]
    server.stdin.close()  # type: ignore[union-attr]
    for p in (publisher, server):
        p.wait(30)
    out: dict[str, Any] = {'slow_clients': n_slow, 'image_bytes': image_bytes, **results[0],
                           'publish_hz': round(pub['sent'] / pub['seconds'], 1)}
    if rounds > 1:
        out['rss_mb_after_leave_by_round'] = [r['rss_mb_after_leave'] for r in results]
        out['rss_mb_peak_by_round'] = [r['rss_mb_peak'] for r in results]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--clients', default='1,10', help='slow client counts, one run each')
    ap.add_argument('--duration', type=float, default=40.0)
    ap.add_argument('--hz', type=float, default=30.0)
    ap.add_argument('--max-rss-mb', type=float, default=10000.0,
                    help='end a run early once the server is this big')
    ap.add_argument('--rounds', type=int, default=1,
                    help='slow clients come and go this many times against the same server')
    ap.add_argument('--serve', action='store_true', help=argparse.SUPPRESS)
    ap.add_argument('--publish', type=float, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.serve:
        return serve()
    if args.publish:
        return publish(args.publish)
    runs = []
    for n in (int(x) for x in args.clients.split(',')):
        runs.append(run(n, args.duration, args.hz, args.max_rss_mb, args.rounds))
        print(runs[-1], flush=True)
    print(json.dumps({'topic': TOPIC, 'duration_s': args.duration, 'runs': runs}))


if __name__ == '__main__':
    main()
