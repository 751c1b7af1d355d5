"""A minimal Foxglove WebSocket client (protocol foxglove.sdk.v1, as the Foxglove app speaks it):
read the advertised channels, subscribe to some topics, keep the first message of each."""

from __future__ import annotations

import asyncio
import json
import struct
import time
from dataclasses import dataclass, field
from typing import Any

import websockets

SUBPROTOCOL = 'foxglove.sdk.v1'
MESSAGE_DATA = 0x01   # binary opcode: subscription id (u32 LE), log time (u64 LE), payload


@dataclass
class Session:
    server_info: dict[str, Any] = field(default_factory=dict)
    # topic -> advertised channel
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)
    first: dict[str, bytes] = field(default_factory=dict)              # topic -> first payload


async def _collect(url: str, topics: set[str], timeout: float) -> Session:
    session = Session()
    subscribed: dict[int, str] = {}
    deadline = time.monotonic() + timeout
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
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


def collect(url: str, topics: set[str], timeout: float = 60.0) -> Session:
    """Connect, subscribe to `topics` as their channels are advertised, return when a message of
    each has arrived or after timeout (the caller checks what is missing)."""
    return asyncio.run(_collect(url, topics, timeout))
