"""A TCP relay in front of foxglove-sdk's WebSocket server that also accepts the protocol's old
name.

foxglove-sdk (0.30) accepts only the WebSocket subprotocol `foxglove.sdk.v1` and answers HTTP 400 to
a client offering only `foxglove.websocket.v1`: Foxglove Studio 1.x, @foxglove/ws-protocol 0.8
clients and Lichtblick before December 2025. Both names are the same protocol, and the SDK has no
option for the name, so the live view listens on the public port with this relay and the SDK on an
internal 127.0.0.1 port. For each connection the relay reads the HTTP upgrade request; one offering
the old name but not the new one is passed on offering `foxglove.sdk.v1`, and the SDK's answer is
given back naming the protocol the client offered. Every other upgrade request goes through
unchanged. Then bytes are copied both ways until either side closes.

Every client goes through the relay, whichever name it offers: the SDK can only accept connections
itself, so it cannot take over one the relay has read from, and a second port for old viewers
would leave them to find it. The cost is a copy of every byte in Python threads (which release the
GIL in recv/send): 0.5-0.6 ms of CPU per MB, up to ~1 GB/s through loopback on the 2-core dev
machine (bench/live_view_viewers.py), so ~2 % of a core for a viewer taking 30 MB/s of images.

Backpressure: each direction is one thread copying RELAY_CHUNK bytes at a time with blocking
sends, and the relay's receive buffer from the SDK is capped (UPSTREAM_RCVBUF), so a client that
stops reading stops the relay reading from the SDK within ~RELAY_CHUNK + UPSTREAM_RCVBUF, and the
SDK's own bounded per-client outbox fills and drops the oldest (live_view.CLIENT_BACKLOG).

A request that is not a WebSocket upgrade (a browser opening the URL) gets 426 Upgrade Required and
one line saying what this server is; the SDK itself closes such connections without an answer.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import threading

log = logging.getLogger('vizzy_runtime.ws_relay')

NEW_NAME = b'foxglove.sdk.v1'
OLD_NAME = b'foxglove.websocket.v1'
# The largest request or response head read (a WebSocket upgrade is a few hundred bytes).
MAX_HEAD = 16 * 1024
# How long a new connection may take to send its request head (a client that connects and says
# nothing holds only its own thread, and not forever).
HEAD_TIMEOUT_S = 10.0
# Bytes copied per read. With UPSTREAM_RCVBUF it bounds what the relay takes from the SDK on
# behalf of a client that is not reading (the kernel doubles SO_RCVBUF for its bookkeeping).
RELAY_CHUNK = 64 * 1024
UPSTREAM_RCVBUF = 64 * 1024
# After the server closed a connection, how long the client may take to close its side.
CLOSE_GRACE_S = 2.0


class HeadError(ValueError):
    """A request or response head that cannot be relayed (too long, closed early, malformed)."""


def read_head(sock: socket.socket) -> tuple[bytes, bytes]:
    """An HTTP head (up to and without the blank line) and whatever followed it in the same read."""
    buf = b''
    while b'\r\n\r\n' not in buf:
        if len(buf) > MAX_HEAD:
            raise HeadError(f'head longer than {MAX_HEAD} bytes')
        chunk = sock.recv(4096)
        if not chunk:
            raise HeadError('closed before the end of the head')
        buf += chunk
    head, rest = buf.split(b'\r\n\r\n', 1)
    if len(head) > MAX_HEAD:
        raise HeadError(f'head longer than {MAX_HEAD} bytes')
    return head, rest


def _header(line: bytes) -> tuple[bytes, bytes]:
    name, _, value = line.partition(b':')
    return name.strip().lower(), value.strip()


def offered(head: bytes) -> list[bytes]:
    """The subprotocols a request head offers, in order (any number of header lines, comma
    lists)."""
    names: list[bytes] = []
    for line in head.split(b'\r\n')[1:]:
        name, value = _header(line)
        if name == b'sec-websocket-protocol':
            names += [v.strip() for v in value.split(b',') if v.strip()]
    return names


def is_upgrade(head: bytes) -> bool:
    return any(name == b'upgrade' and b'websocket' in value.lower()
               for name, value in map(_header, head.split(b'\r\n')[1:]))


def rewrite_request(head: bytes) -> tuple[bytes, bool]:
    """The head to pass to the SDK, and whether the old name was swapped for the new one (only when
    the client offers the old name and not the new: then the SDK would answer 400)."""
    names = offered(head)
    if NEW_NAME in names or OLD_NAME not in names:
        return head, False
    lines = [line for line in head.split(b'\r\n')
             if _header(line)[0] != b'sec-websocket-protocol']
    lines.append(b'Sec-WebSocket-Protocol: ' + NEW_NAME)
    return b'\r\n'.join(lines), True


def rewrite_response(head: bytes) -> bytes:
    """The SDK's answer to a rewritten request, naming the protocol the way the client offered it
    (a WebSocket client must fail a connection whose protocol it did not offer)."""
    lines = head.split(b'\r\n')
    for i, line in enumerate(lines[1:], 1):
        name, value = _header(line)
        if name == b'sec-websocket-protocol' and value == NEW_NAME:
            lines[i] = line.split(b':', 1)[0] + b': ' + OLD_NAME
    return b'\r\n'.join(lines)


def _answer(status: str, text: str) -> bytes:
    body = (text + '\n').encode()
    return (f'HTTP/1.1 {status}\r\nContent-Type: text/plain; charset=utf-8\r\n'
            f'Content-Length: {len(body)}\r\nConnection: close\r\n'
            + ('Upgrade: websocket\r\n' if status.startswith('426') else '')
            + '\r\n').encode() + body


class WsRelay:
    """Listens on (host, port) and relays each connection to the WebSocket server on
    (target_host, target_port), accepting both subprotocol names (see the module docstring).
    start() returns the port bound (port 0: a free one); stop() closes the listener and every
    relayed connection."""

    def __init__(self, host: str, port: int, target_port: int,
                 target_host: str = '127.0.0.1') -> None:
        self.host, self.requested_port = host, port
        self.target = (target_host, target_port)
        self.port = 0
        self.renamed = 0          # connections accepted through the old name
        self._listener: socket.socket | None = None
        self._lock = threading.Lock()
        self._open: set[socket.socket] = set()
        self._stopping = threading.Event()

    def start(self) -> int:
        family = socket.AF_INET6 if ':' in self.host else socket.AF_INET
        # as the SDK's own listener did (reuse: a restarted view binds the port again at once)
        self._listener = socket.create_server((self.host, self.requested_port), family=family,
                                              backlog=64)
        self.port = self._listener.getsockname()[1]
        threading.Thread(target=self._accept_loop, name='ws_relay', daemon=True).start()
        return self.port

    def stop(self) -> None:
        self._stopping.set()
        if self._listener is not None:
            with contextlib.suppress(OSError):
                self._listener.shutdown(socket.SHUT_RDWR)   # wakes accept() on Linux
            self._listener.close()
        with self._lock:
            socks, self._open = set(self._open), set()
        for sock in socks:
            _kill(sock)

    def _track(self, sock: socket.socket) -> bool:
        with self._lock:
            if self._stopping.is_set():
                return False
            self._open.add(sock)
            return True

    def _forget(self, *socks: socket.socket) -> None:
        with self._lock:
            self._open.difference_update(socks)
        for sock in socks:
            sock.close()

    def _accept_loop(self) -> None:
        assert self._listener is not None
        while not self._stopping.is_set():
            try:
                client, _addr = self._listener.accept()
            except OSError:
                if self._stopping.is_set():
                    return
                continue   # e.g. the peer reset before accept: go on serving
            if not self._track(client):
                client.close()
                return
            threading.Thread(target=self._serve, args=(client,), name='ws_relay_conn',
                             daemon=True).start()

    def _serve(self, client: socket.socket) -> None:
        upstream = None
        try:
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            client.settimeout(HEAD_TIMEOUT_S)
            try:
                head, rest = read_head(client)
            except (HeadError, TimeoutError) as exc:
                client.sendall(_answer('400 Bad Request', f'not an HTTP request: {exc}'))
                return
            if not is_upgrade(head):
                client.sendall(_answer(
                    '426 Upgrade Required',
                    'This is a Foxglove WebSocket server (subprotocol foxglove.sdk.v1 or '
                    'foxglove.websocket.v1): open it in the Foxglove app or Lichtblick with '
                    '"Open connection > Foxglove WebSocket".'))
                return
            head, renamed = rewrite_request(head)
            upstream = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            upstream.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UPSTREAM_RCVBUF)
            upstream.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            if not self._track(upstream):
                return
            upstream.settimeout(HEAD_TIMEOUT_S)
            upstream.connect(self.target)
            upstream.sendall(head + b'\r\n\r\n' + rest)
            if renamed:
                answer, more = read_head(upstream)
                client.sendall(rewrite_response(answer) + b'\r\n\r\n' + more)
                if b' 101 ' in answer.split(b'\r\n', 1)[0]:
                    with self._lock:
                        self.renamed += 1
            client.settimeout(None)
            upstream.settimeout(None)
            up = threading.Thread(target=_pump, args=(client, upstream), name='ws_relay_up',
                                  daemon=True)
            up.start()
            _pump(upstream, client)
            # the server is done: the client has a moment to close its side, then both are ended
            up.join(CLOSE_GRACE_S)
            _kill(client)
            _kill(upstream)
            up.join()
        except (OSError, HeadError) as exc:
            if not self._stopping.is_set():
                log.info('live view relay: connection dropped: %s', exc)
        finally:
            self._forget(client, *([upstream] if upstream is not None else []))


def _kill(sock: socket.socket) -> None:
    with contextlib.suppress(OSError):
        sock.shutdown(socket.SHUT_RDWR)


def _pump(src: socket.socket, dst: socket.socket) -> None:
    """Copy src to dst until src ends (then end dst's sending side) or either fails (then end both,
    which also ends the pump of the other direction). Blocking sends: a reader that stalls stops
    this copy, and so backs up into the sender."""
    buf = bytearray(RELAY_CHUNK)
    view = memoryview(buf)
    try:
        while True:
            n = src.recv_into(buf)
            if not n:
                with contextlib.suppress(OSError):
                    dst.shutdown(socket.SHUT_WR)
                return
            dst.sendall(view[:n])
    except OSError:
        _kill(src)
        _kill(dst)
