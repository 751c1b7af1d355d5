"""Which viewers the live view accepts, and what its relay costs (issue 29 item 7).

1. The handshake answer of a LiveView (live_view.py) to a WebSocket upgrade offering each
   subprotocol name (foxglove.sdk.v1: the Foxglove app, Lichtblick from December 2025;
   foxglove.websocket.v1: Foxglove Studio 1.x, older Lichtblick, @foxglove/ws-protocol 0.8
   clients), and to a plain HTTP GET. Before the relay (ws_relay.py) the old name got HTTP 400.
2. The relay's CPU per MB relayed: a WsRelay alone in a child process between a stand-in server
   that answers 101 and then writes --mb 1 MB blocks, and a client here that reads them all; the
   child's utime + stime (/proc/<pid>/stat) over the transfer.

    .venv/bin/python bench/live_view_viewers.py [--mb 400] [--rounds 3]
"""

from __future__ import annotations

import argparse
import base64
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from vizzy_runtime.live_view import LiveView

OFFERS = ['foxglove.sdk.v1', 'foxglove.websocket.v1', 'foxglove.websocket.v1, foxglove.sdk.v1']


def _upgrade(offer: str) -> bytes:
    key = base64.b64encode(os.urandom(16)).decode()
    return (f'GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n'
            f'Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n'
            f'Sec-WebSocket-Protocol: {offer}\r\n\r\n').encode()


def answer(port: int, request: bytes) -> str:
    """The status line and protocol header of the answer ('' when closed without one)."""
    with socket.create_connection(('127.0.0.1', port), timeout=10) as sock:
        sock.sendall(request)
        buf = b''
        while b'\r\n\r\n' not in buf and (chunk := sock.recv(65536)):
            buf += chunk
    lines = buf.split(b'\r\n\r\n')[0].decode(errors='replace').split('\r\n')
    proto = [line for line in lines if line.lower().startswith('sec-websocket-protocol')]
    return ' | '.join([lines[0] or '(closed, no answer)', *proto])


def handshakes() -> None:
    view = LiveView(port=0)
    port = view.start()
    try:
        for offer in OFFERS:
            print(f'offer {offer!r:42} -> {answer(port, _upgrade(offer))}')
        plain = answer(port, b'GET / HTTP/1.1\r\nHost: x\r\n\r\n')
        print(f'{"plain GET":48} -> {plain}')
    finally:
        view.stop()


def relay_cpu(total_mb: int) -> None:
    server = socket.create_server(('127.0.0.1', 0))

    def serve() -> None:
        conn, _ = server.accept()
        buf = b''
        while b'\r\n\r\n' not in buf:
            buf += conn.recv(4096)
        conn.sendall(b'HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n'
                     b'Connection: Upgrade\r\nsec-websocket-protocol: foxglove.sdk.v1\r\n\r\n')
        block = os.urandom(1 << 20)
        for _ in range(total_mb):
            conn.sendall(block)
        conn.close()

    threading.Thread(target=serve, daemon=True).start()
    child = subprocess.Popen([sys.executable, '-c', (
        'import time\nfrom vizzy_runtime.ws_relay import WsRelay\n'
        f'r = WsRelay("127.0.0.1", 0, {server.getsockname()[1]})\n'
        'print(r.start(), flush=True)\ntime.sleep(600)')], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None
        port = int(child.stdout.readline())

        def cpu() -> float:
            stat = Path(f'/proc/{child.pid}/stat').read_text()
            fields = stat.rsplit(')', 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')

        c0, t0 = cpu(), time.monotonic()
        got, buf = 0, bytearray(1 << 20)
        with socket.create_connection(('127.0.0.1', port)) as sock:
            sock.sendall(_upgrade('foxglove.websocket.v1'))
            while n := sock.recv_into(buf):
                got += n
        c1, t1 = cpu(), time.monotonic()
    finally:
        child.kill()
        child.wait()
        server.close()
    mb = got / 1e6
    print(f'relayed {mb:.0f} MB in {t1 - t0:.2f} s ({mb / (t1 - t0):.0f} MB/s): relay CPU '
          f'{c1 - c0:.2f} s = {1000 * (c1 - c0) / mb:.2f} ms per MB')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--mb', type=int, default=400)
    parser.add_argument('--rounds', type=int, default=3)
    args = parser.parse_args()
    handshakes()
    for _ in range(args.rounds):
        relay_cpu(args.mb)


if __name__ == '__main__':
    main()
