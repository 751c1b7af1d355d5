"""Live view: the graph's topics served to Foxglove over WebSocket, without ROS (foxglove-sdk).

    vizzy view [--port 8765] [--host 127.0.0.1]     # a running graph, or a bag being played
    vizzy launch / make demo                         # start one by default (--no-view, --view-port)

Every topic with a publisher on the DDS domain becomes a channel named like the topic, with the
message's ROS 2 schema (schema encoding ros2msg, message encoding cdr): the Foxglove app decodes
images, compressed images, point clouds, markers, tf, /rosout and /diagnostics with its built-in
ROS 2 support, no plugin and no ROS installation. The CDR bytes are passed through untouched.

A topic is read from DDS only while some client subscribes to it, so an idle server costs only
discovery. Latched topics (transient local: /tf_static, /robot_description) are read again from
their publishers for each new subscription, so a client that connects late still gets them.

Memory: each client's outbox holds at most CLIENT_BACKLOG messages (foxglove-sdk's
message_backlog_size; the oldest data message is dropped when it is full), so a client that reads
slower than the graph, or not at all, gets the newest messages and costs at most
(CLIENT_BACKLOG + 1) x its largest message: 30 MB of VGA images, not the SDK default's 0.9 GB. Of
the images and clouds a reader has queued only the newest is passed on. After a client leaves, the
freed outboxes are handed back to the system (malloc_trim).

The view listens on 127.0.0.1 (the networking default); with the LAN opt-in (VIZZY_DDS_LAN=1) on
every interface. Open it in the Foxglove app (Open connection > Foxglove WebSocket) and import the
layout `config/foxglove_layout.json` (`foxglove_layout.py` makes it).

Viewers: foxglove-sdk accepts only the subprotocol name `foxglove.sdk.v1` (the Foxglove app,
Lichtblick from December 2025); older viewers (Foxglove Studio 1.x, Lichtblick before, clients of
@foxglove/ws-protocol 0.8) offer only `foxglove.websocket.v1`, the same protocol. So the public port
is a relay (ws_relay.py) that accepts both names, in front of the SDK's server on an internal
127.0.0.1 port; every client goes through it (0.5-0.6 ms of CPU per MB relayed).
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import threading
import time
from collections import Counter
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, cast

from . import loopback, msgs
from .ws_relay import WsRelay

if TYPE_CHECKING:
    from foxglove.websocket import ServerListener

log = logging.getLogger('vizzy_runtime.live_view')

DEFAULT_PORT = 8765
# Samples kept by a reader between takes: a subscriber wants the newest (an image is 0.9 MB).
DEPTH = 4
# The per-client memory bound. foxglove-sdk bounds what it holds for a client only by a count,
# message_backlog_size: each client has its own outbox (every queued message is that client's copy
# of the payload, framed with its subscription id); when the data outbox is full the oldest message
# is dropped, so a slow client gets the newest, and a full control outbox (the same size)
# disconnects the client. A client that never reads thus holds at most (backlog + 1 frame being
# written) x the largest message it subscribed to: with 32, 30 MB of VGA images (0.9 MB) or 160 MB
# of the RGB-D organized cloud (4.9 MB); the SDK default 1024 let one such client hold 0.9 GB.
# The count is also what a reading client may fall behind by before it loses messages: the whole
# graph sends ~400 messages/s, in bursts (the RGB-D set is 7 MB at once); a reading client in its
# own process on a loaded 2-core machine lost 0.2-1.2 % of them with 16, 0-0.3 % with 32 (load 15).
# That holds provided the view itself never hands the SDK many messages at once: BURST_PAUSE_S.
CLIENT_BACKLOG = 32
# Faster than any client can be served, a burst (channels advertised together, a latched topic's
# samples replayed) would overflow a small outbox: a reading client would lose latched samples or
# be disconnected for advertisements. The view's own bursts go out half a backlog at a time,
# BURST_PAUSE_S apart, time in which a reading client's outbox drains many times over.
BURST_PAUSE_S = 0.01
# Whole frames: of those a reader has queued only the newest is worth sending (newest wins per
# channel, as a viewer wants); other topics (/tf, markers) carry parts of the state in each message.
FRAME_TYPES = frozenset({
    'sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage', 'sensor_msgs/msg/PointCloud2',
    'sensor_msgs/msg/LaserScan',
})
# After a client leaves: its outbox (up to CLIENT_BACKLOG frames) went back to glibc's arenas,
# which keep it; malloc_trim returns it to the system. A second lets the SDK drop the client.
TRIM_AFTER_S = 1.0


def _hidden(topic: str) -> bool:
    return any(part.startswith('_') for part in topic.split('/'))


def to_send(samples: Sequence[tuple[bytes, int]], typename: str) -> list[bytes]:
    """The payloads of a take worth sending: all of them, or of whole frames only the newest."""
    if typename in FRAME_TYPES:
        return [samples[-1][0]] if samples else []
    return [data for data, _source_ns in samples]


def _malloc_trim() -> None:
    """Return free heap memory to the system (glibc; elsewhere nothing to do)."""
    with contextlib.suppress(OSError, AttributeError):  # not glibc
        ctypes.CDLL('libc.so.6').malloc_trim(0)


class LiveView:
    """A foxglove-sdk WebSocket server bridging the DDS graph's topics (see the module docstring).

    start() returns the port actually bound (pass port=0 for a free one); stop() closes the server
    and every reader. `channels` maps each served topic to its type, `sent` counts messages logged.
    """

    def __init__(self, host: str | None = None, port: int = DEFAULT_PORT, *, name: str = 'vizzy',
                 discovery_interval: float = 0.5, client_backlog: int = CLIENT_BACKLOG) -> None:
        self.host = loopback.default_bind_host() if host is None else host
        self.requested_port = port
        self.name = name
        self.discovery_interval = discovery_interval
        self.client_backlog = client_backlog
        self._burst = max(1, client_backlog // 2)
        self.channels: dict[str, str] = {}
        self.sent: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._channel_objs: dict[str, Any] = {}
        self._offers: dict[str, list[Any]] = {}
        self._subscribers: dict[str, set[int]] = {}
        self._refresh: set[str] = set()      # latched topics with a new subscriber: read again
        self._readers: dict[str, Any] = {}
        self._skipped: set[str] = set()
        self._trim_at: float | None = None   # monotonic time to give a left client's memory back
        self._server: Any = None
        self._relay: WsRelay | None = None
        self._thread: threading.Thread | None = None

    # -- lifecycle ---------------------------------------------------------------------------------

    def start(self) -> int:
        import foxglove

        from . import dds
        self._context = foxglove.Context()
        self._discovery = dds.Discovery()
        # the SDK's own server only on loopback, reached through the relay (ws_relay.py)
        self._server = foxglove.start_server(
            name=self.name, host=loopback.LOOPBACK_V4, port=0, context=self._context,
            # the server calls only the callbacks a listener has (on_subscribe, on_unsubscribe)
            server_listener=cast('ServerListener', self), capabilities=[],
            message_backlog_size=self.client_backlog)
        relay = WsRelay(self.host, self.requested_port, target_port=int(self._server.port))
        try:
            relay.start()
        except BaseException:   # the public port is taken or bad: nothing left running
            self._server.stop()
            self._server = None
            raise
        self._relay = relay
        self._thread = threading.Thread(target=self._loop, name='live_view', daemon=True)
        self._thread.start()
        return self.port

    @property
    def port(self) -> int:
        """The public port (the relay's), where viewers connect."""
        return self._relay.port if self._relay is not None else 0

    @property
    def sdk_port(self) -> int:
        """The SDK server's internal loopback port (tests; viewers use `port`)."""
        return int(self._server.port) if self._server is not None else 0

    @property
    def url(self) -> str:
        # a server on every interface is reached here through loopback
        host = loopback.LOOPBACK_V4 if self.host in (loopback.WILDCARD_V4, '') else self.host
        return f'ws://{host}:{self.port}'

    def stop(self) -> None:
        from . import dds
        self._stopping.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(5)
        with self._lock:
            readers, self._readers = self._readers, {}
        for reader in readers.values():
            dds.delete(reader)
        if self._relay is not None:
            self._relay.stop()
            self._relay = None
        if self._server is not None:
            self._server.stop()
            self._server = None

    # -- foxglove ServerListener (called from the server's threads: note and wake the loop) -------

    def on_subscribe(self, client: Any, channel: Any) -> None:
        with self._lock:
            self._subscribers.setdefault(channel.topic, set()).add(client.id)
            self._refresh.add(channel.topic)
        self._wake.set()

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        with self._lock:
            self._subscribers.get(channel.topic, set()).discard(client.id)
            # also called when a client leaves, before the SDK frees its outbox
            self._trim_at = time.monotonic() + TRIM_AFTER_S
        self._wake.set()

    # -- the loop: discovery, channels, readers ----------------------------------------------------

    def _loop(self) -> None:
        while not self._stopping.is_set():
            try:
                self._advertise_new()
                self._reconcile_readers()
                self._trim_if_due()
            except Exception as exc:  # noqa: BLE001 - the view must never take its host down
                log.warning('live view: %s', exc)
            self._wake.wait(self.discovery_interval)
            self._wake.clear()

    def _trim_if_due(self) -> None:
        with self._lock:
            due = self._trim_at is not None and time.monotonic() >= self._trim_at
            if due:
                self._trim_at = None
        if due:
            _malloc_trim()

    def _advertise_new(self) -> None:
        import foxglove
        offers: dict[str, list[Any]] = {}
        types: dict[str, str] = {}
        for ep in self._discovery.endpoints():
            if ep.is_writer and not _hidden(ep.topic):
                offers.setdefault(ep.topic, []).append(ep.qos)
                types.setdefault(ep.topic, ep.typename)
        created = 0
        for topic, typename in sorted(types.items()):
            if topic in self._channel_objs or topic in self._skipped:
                continue
            if created and created % self._burst == 0:
                time.sleep(BURST_PAUSE_S)   # each channel is one advertisement to every client
            created += 1
            try:
                schema = foxglove.Schema(name=typename, encoding='ros2msg',
                                         data=msgs.message_definition(typename).encode())
            except Exception as exc:  # noqa: BLE001 - a type we have no definition for
                log.warning('live view: not serving %s [%s]: %s', topic, typename, exc)
                self._skipped.add(topic)
                continue
            self._channel_objs[topic] = foxglove.Channel(topic, schema=schema,
                                                         message_encoding='cdr',
                                                         context=self._context)
            self.channels[topic] = typename
        with self._lock:
            self._offers.update(offers)

    def _reconcile_readers(self) -> None:
        from . import dds
        with self._lock:
            wanted = {t for t, clients in self._subscribers.items() if clients
                      and t in self.channels}
            refresh, self._refresh = self._refresh & wanted, set()
            offers = dict(self._offers)
        for topic in list(self._readers):
            latched = self._readers[topic].qos.transient_local
            if topic not in wanted or (topic in refresh and latched):
                dds.delete(self._readers.pop(topic))
        for topic in sorted(wanted - set(self._readers)):
            qos = offers.get(topic, [])
            latched = bool(qos) and all(q.transient_local for q in qos)
            reliable = bool(qos) and all(q.reliable for q in qos)
            request = dds.QoS(reliable=latched and reliable, transient_local=latched,
                              depth=100 if latched else DEPTH)
            try:
                self._readers[topic] = dds.RawReader(topic, self.channels[topic], request,
                                                     on_data=self._on_data)
            except Exception as exc:  # noqa: BLE001 - e.g. a type that disagrees with the peer's
                log.warning('live view: cannot read %s: %s', topic, exc)

    def _on_data(self, reader: Any) -> None:
        """Cyclone's listener thread: pass the CDR bytes on (never raise into Cyclone)."""
        try:
            channel = self._channel_objs.get(reader.topic_name)
            samples = reader.take(64)
            if channel is None:
                return
            now = time.time_ns()
            payloads = to_send(samples, reader.typename)
            for i, data in enumerate(payloads):
                if i and i % self._burst == 0:
                    time.sleep(BURST_PAUSE_S)  # a latched topic's replay: let outboxes drain
                channel.log(data, log_time=now)
            self.sent[reader.topic_name] += len(payloads)
        except Exception as exc:  # noqa: BLE001
            log.warning('live view: %s: %s', reader.topic_name, exc)


def start_or_warn(port: int | None, host: str | None = None) -> LiveView | None:
    """A started LiveView, or None with one line saying why (the port is taken: another demo on
    this machine); port None means off. For `vizzy launch` and `make demo`, which go on without."""
    if port is None:
        return None
    view = LiveView(host=host, port=port)
    try:
        view.start()
    except Exception as exc:  # noqa: BLE001 - e.g. address in use: the graph runs without a view
        print(f'vizzy: live view off: cannot serve on {view.host}:{port} ({exc}); '
              'choose another with --view-port', flush=True)
        return None
    print(f'vizzy: live view on {view.url} (Foxglove: Open connection > Foxglove WebSocket; '
          'layout: src/vizzy_runtime/config/foxglove_layout.json)', flush=True)
    return view
