"""Minimal Foxglove WebSocket clients (protocol foxglove.sdk.v1, as the Foxglove app speaks it, or
its old name foxglove.websocket.v1, as Foxglove Studio 1.x and older Lichtblick offer it):
collect() reads the advertised channels, subscribes to some topics and keeps the first message of
each; RawClient is a blocking socket with just enough WebSocket to subscribe, which reads only when
told to (a client that stops reading: the live view's memory bound, bench/live_view_memory.py)."""

from __future__ import annotations

import asyncio
import base64
import json
import os
import socket
import struct
import time
from dataclasses import dataclass, field
from typing import Any

import websockets

from vizzy_runtime.testing import scaled

SUBPROTOCOL = 'foxglove.sdk.v1'
OLD_SUBPROTOCOL = 'foxglove.websocket.v1'   # the same protocol, the name older viewers offer
MESSAGE_DATA = 0x01   # binary opcode: subscription id (u32 LE), log time (u64 LE), payload


@dataclass
class Session:
    server_info: dict[str, Any] = field(default_factory=dict)
    # topic -> advertised channel
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)
    first: dict[str, bytes] = field(default_factory=dict)              # topic -> first payload
    subprotocol: str | None = None                                     # what the server chose


async def _collect(url: str, topics: set[str], timeout: float,
                   subprotocols: list[str]) -> Session:
    session = Session()
    subscribed: dict[int, str] = {}
    deadline = time.monotonic() + timeout
    # websockets fails the handshake if the server names a protocol the client did not offer
    async with websockets.connect(url, subprotocols=subprotocols,  # type: ignore[arg-type]
                                  max_size=None) as ws:
        session.subprotocol = ws.subprotocol
        while time.monotonic() < deadline and not topics <= set(session.first):
            try:
                frame = await asyncio.wait_for(ws.recv(),
                                               timeout=max(0.1, deadline - time.monotonic()))
            except asyncio.TimeoutError:
                break
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get('op') == 'serverInfo':
                    session.server_info = msg
                elif msg.get('op') == 'advertise':
                    new = []
                    for ch in msg['channels']:
                        session.channels[ch['topic']] = ch
                        if ch['topic'] in topics:
                            sub_id = len(subscribed) + 1
                            subscribed[sub_id] = ch['topic']
                            new.append({'id': sub_id, 'channelId': ch['id']})
                    if new:
                        await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': new}))
            elif frame and frame[0] == MESSAGE_DATA:
                sub_id, _log_time = struct.unpack_from('<IQ', frame, 1)
                topic = subscribed.get(sub_id)
                if topic is not None:
                    session.first.setdefault(topic, bytes(frame[13:]))
    return session


def collect(url: str, topics: set[str], timeout: float = scaled(60.0),
            subprotocols: tuple[str, ...] = (SUBPROTOCOL,)) -> Session:
    """Connect offering `subprotocols`, subscribe to `topics` as their channels are advertised,
    return when a message of each has arrived or after timeout (the caller checks what is
    missing)."""
    return asyncio.run(_collect(url, topics, timeout, list(subprotocols)))


class RawClient:
    """A Foxglove client on a plain blocking socket: nothing is read unless frame() is called, so
    the server's writes stall once the socket's receive buffer (rcvbuf, set before connecting, so
    the window the server sees is small from the start) is full."""

    def __init__(self, port: int, rcvbuf: int | None = None, host: str = '127.0.0.1',
                 subprotocols: tuple[str, ...] = (SUBPROTOCOL,)) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if rcvbuf:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.connect((host, port))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f'GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n'
                           f'Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n'
                           f'Sec-WebSocket-Version: 13\r\n'
                           f'Sec-WebSocket-Protocol: {", ".join(subprotocols)}'
                           '\r\n\r\n').encode())
        self.buf = b''
        self.channels: dict[str, dict[str, Any]] = {}   # topic -> advertised channel
        self.subscribe_text = ''                          # the last subscribe request sent
        while b'\r\n\r\n' not in self.buf:
            self.buf += self._recv()
        head, self.buf = self.buf.split(b'\r\n\r\n', 1)
        if b' 101 ' not in head.split(b'\r\n')[0]:
            raise ConnectionError(f'handshake refused: {head[:200]!r}')
        # the protocol the server chose (a real client fails one it did not offer)
        self.subprotocol = next((line.split(b':', 1)[1].strip().decode()
                                 for line in head.split(b'\r\n')
                                 if line.lower().startswith(b'sec-websocket-protocol:')), None)

    def _recv(self) -> bytes:
        chunk = self.sock.recv(1 << 20)
        if not chunk:
            raise ConnectionError('closed by the server')
        return chunk

    def _need(self, n: int) -> None:
        while len(self.buf) < n:
            self.buf += self._recv()

    def frame(self) -> tuple[int, bytes]:
        """The next WebSocket frame (opcode, payload); advertisements are noted in `channels`."""
        self._need(2)
        opcode, size = self.buf[0] & 0x0F, self.buf[1] & 0x7F
        at = 2
        if size == 126:
            self._need(4)
            size, at = struct.unpack_from('>H', self.buf, 2)[0], 4
        elif size == 127:
            self._need(10)
            size, at = struct.unpack_from('>Q', self.buf, 2)[0], 10
        self._need(at + size)
        payload, self.buf = self.buf[at:at + size], self.buf[at + size:]
        if opcode == 1:
            msg = json.loads(payload)
            if msg.get('op') == 'advertise':
                self.channels.update((ch['topic'], ch) for ch in msg['channels'])
        elif opcode == 8:
            raise ConnectionError(f'closed by the server: {self.buf!r}')
        return opcode, payload

    def data(self) -> tuple[int, bytes]:
        """The next message data (subscription id, payload), skipping other frames."""
        while True:
            opcode, payload = self.frame()
            if opcode == 2 and payload[:1] == bytes([MESSAGE_DATA]):
                return struct.unpack_from('<I', payload, 1)[0], payload[13:]

    def send_text(self, text: str) -> None:
        data, mask = text.encode(), os.urandom(4)
        size = len(data)
        head = bytes([0x81]) + (bytes([0x80 | size]) if size < 126
                                else bytes([0x80 | 126]) + struct.pack('>H', size))
        self.sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))

    def subscribe(self, topic: str, timeout: float = scaled(60.0), sub_id: int = 1) -> None:
        """Read until `topic` is advertised, then subscribe to it as `sub_id`."""
        deadline = time.monotonic() + timeout
        self.sock.settimeout(timeout)
        try:
            while topic not in self.channels:
                if time.monotonic() > deadline:
                    raise TimeoutError(f'{topic} was never advertised')
                self.frame()
        finally:
            self.sock.settimeout(None)
        self.subscribe_text = json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': sub_id, 'channelId': self.channels[topic]['id']}]})
        self.send_text(self.subscribe_text)

    def close(self) -> None:
        self.sock.close()
