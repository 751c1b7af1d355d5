"""VGA images across vendors: from a bundled-runtime (Cyclone DDS) publisher process and from a
real-rclpy (rmw_fastrtps_cpp, .venv-ros) one, a subscriber process of the other vendor receives
(close to) what a subscriber process of the publisher's own vendor receives in the same run.

Sensor-data QoS (best effort) at 15 Hz, as the simulator publishes. Before the real-rclpy tier's
Fast DDS profile (config/fastdds_loopback.xml: 8 MiB UDP receive buffer) a Fast DDS subscriber got
about half the frames a Cyclone publisher sent: each 921,600-byte image arrives as one burst of
64 KB datagrams, more than the kernel's default socket buffer holds. See docs/architecture.md,
"Networking". Skipped where .venv-ros could not be set up."""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from vizzy_runtime.testing import real_rclpy_env, real_rclpy_python, scaled

pytestmark = pytest.mark.slow  # starts processes or a whole graph, or takes more than ~5 s

PEER = Path(__file__).with_name('image_peer.py')
FRAMES = 60
RATE_HZ = 15.0
START_S = scaled(90.0)   # process start and discovery, on a loaded 2-core machine
# after the last image was sent, for every subscriber to have read everything
DRAIN_S = scaled(30.0)
QUIET_S = 5.0    # ... or to have read nothing more for this long


class Peer:
    """An image_peer.py process on one runtime; its stdout lines arrive in a queue."""

    def __init__(self, runtime: str, *args: str) -> None:
        if runtime == 'real':
            python, env = str(real_rclpy_python()), real_rclpy_env()
        else:
            python, env = sys.executable, {**os.environ, 'VIZZY_RUNTIME': 'bundled'}
        self.runtime = runtime
        self.proc = subprocess.Popen([python, str(PEER), *args], env=env, text=True,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.lines: queue.Queue[str] = queue.Queue()
        self.got = 0
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.strip())
        self.lines.put('<exited>')

    def expect(self, word: str, deadline: float) -> str:
        """The next line starting with word (counting `got N` lines on the way)."""
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f'{self.runtime} peer: no {word!r} in time') from None
            if line.startswith('got '):
                self.got = int(line.split()[1])
            if line.startswith(word):
                return line
            assert line != '<exited>', f'{self.runtime} peer exited (rc {self.proc.wait()})'

    def poll_got(self) -> int:
        while True:
            try:
                line = self.lines.get_nowait()
            except queue.Empty:
                return self.got
            if line.startswith('got '):
                self.got = int(line.split()[1])

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + '\n')
        self.proc.stdin.flush()

    def stop(self) -> None:
        try:
            self.send('stop')
            self.proc.wait(timeout=scaled(30))
        except (OSError, subprocess.TimeoutExpired):
            pass
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


@pytest.mark.parametrize('publisher', ['bundled', 'real'])
def test_vga_images_cross_vendors_as_within_one(publisher: str) -> None:
    real_rclpy_python()  # skips where there is no real rclpy
    other = 'real' if publisher == 'bundled' else 'bundled'
    topic = f'/mixed_transport/{publisher}_image'
    peers: list[Peer] = []
    try:
        subs = {runtime: Peer(runtime, 'sub', topic) for runtime in (publisher, other)}
        peers += subs.values()
        pub = Peer(publisher, 'pub', topic, '2', str(FRAMES), str(RATE_HZ))
        peers.append(pub)
        deadline = time.monotonic() + START_S
        for peer in peers:
            peer.expect('ready', deadline)
        for peer in peers:  # each subscriber sees the publisher, the publisher both subscribers
            peer.expect('matched', deadline)
        pub.send('go')
        sent = int(pub.expect('sent', time.monotonic() + START_S + FRAMES / RATE_HZ).split()[1])
        assert sent == FRAMES
        # until every subscriber has every image, or none got one more for QUIET_S (best effort
        # may lose one), within DRAIN_S
        deadline = time.monotonic() + DRAIN_S
        counts, changed = None, time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - changed < QUIET_S:
            now_counts = [s.poll_got() for s in subs.values()]
            if min(now_counts) >= sent:
                break
            if now_counts != counts:
                counts, changed = now_counts, time.monotonic()
            time.sleep(0.05)
        same, cross = subs[publisher].got, subs[other].got
        assert same > 0, f'the {publisher} subscriber got nothing of {sent}'
        assert cross >= 0.9 * same, (f'{publisher} -> {other}: {cross} of {sent} images, '
                                     f'{publisher} -> {publisher}: {same}')
    finally:
        for peer in peers:
            peer.stop()
