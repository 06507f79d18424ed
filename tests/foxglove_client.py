"""A Foxglove WebSocket client for the tests and benchmarks: the protocol as the Foxglove app
speaks it, with the ``websockets`` package and no code of the server under test.

It offers the subprotocols ``foxglove.sdk.v1`` (the name the SDK's server accepts; the messages
are those of ``foxglove.websocket.v1``) and ``foxglove.websocket.v1``, receives ``serverInfo``
and ``advertise``, sends ``subscribe``, and decodes the binary message-data frames (opcode
0x01, subscription id u32, timestamp u64 ns, payload) against the schema the server
advertised: ``ros2msg`` text through a rosbags typestore built from that text alone,
``protobuf`` through the advertised FileDescriptorSet.
"""
from __future__ import annotations

import asyncio
import base64
import json
import queue
import struct
import threading
import time
from collections.abc import Callable
from typing import Any

import websockets
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

SUBPROTOCOLS = ['foxglove.sdk.v1', 'foxglove.websocket.v1']
SECTION = '=' * 80 + '\n'


class LineReader:
    """Lines of a process's stream, read by a thread, waited for with a deadline."""

    def __init__(self, stream: Any) -> None:
        self.lines: list[str] = []
        self._queue: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream: Any) -> None:
        for line in stream:
            self._queue.put(line)
        self._queue.put('')     # end of the stream: the process has exited

    def wait_for(self, needle: str, deadline: float) -> str:
        end = time.monotonic() + deadline
        while True:
            try:
                line = self._queue.get(timeout=max(0.0, min(0.2, end - time.monotonic())))
                if not line:
                    raise AssertionError(f'process ended before {needle!r}:\n'
                                         + ''.join(self.lines))
                self.lines.append(line)
                if needle in line:
                    return line
            except queue.Empty:
                if time.monotonic() > end:
                    raise AssertionError(f'no {needle!r} within {deadline} s; got:\n'
                                         + ''.join(self.lines)) from None


def ros2msg_store(name: str, text: str) -> Any:
    """A typestore knowing only the types of one advertised ``ros2msg`` schema."""
    store = get_typestore(Stores.EMPTY)
    sections = text.split(SECTION)
    types = dict(get_types_from_msg(sections[0], name))
    for section in sections[1:]:
        head, _, body = section.partition('\n')
        assert head.startswith('MSG: '), head
        sub = head[5:].strip()
        if sub.count('/') == 1:
            sub = sub.replace('/', '/msg/')
        types.update(get_types_from_msg(body, sub))
    store.register(types)
    return store


def protobuf_class(name: str, schema_b64: str) -> Any:
    """The message class of an advertised protobuf schema (base64 FileDescriptorSet)."""
    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(schema_b64))
    pool = descriptor_pool.DescriptorPool()
    for file in fds.file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


class Decoded:
    """Messages received per topic: (websocket timestamp [ns], decoded message), and the
    system-clock time [ns] each arrived at."""

    def __init__(self) -> None:
        self.channels: dict[str, dict[str, Any]] = {}
        self.messages: dict[str, list[tuple[int, Any]]] = {}
        self.arrivals: dict[str, list[int]] = {}


async def receive(port: int, topics: list[str], done: Callable[[Decoded], bool],
                  deadline: float, on_subscribed: Callable[[], None] | None = None) -> Decoded:
    """Connect, subscribe ``topics``, decode messages until ``done(decoded)`` is true."""
    out = Decoded()
    end = time.monotonic() + deadline

    async def recv(ws: Any) -> Any:
        try:
            return await asyncio.wait_for(ws.recv(), max(0.0, end - time.monotonic()))
        except TimeoutError:
            raise AssertionError(f'deadline {deadline} s passed; received '
                                 f'{ {k: len(v) for k, v in out.messages.items()} }') from None

    async with websockets.connect(f'ws://127.0.0.1:{port}', subprotocols=SUBPROTOCOLS,
                                  max_size=None, open_timeout=deadline) as ws:
        assert ws.subprotocol in SUBPROTOCOLS
        info = json.loads(await recv(ws))
        assert info['op'] == 'serverInfo', info
        while not set(topics) <= set(out.channels):
            msg = await recv(ws)
            if isinstance(msg, str) and json.loads(msg)['op'] == 'advertise':
                for chan in json.loads(msg)['channels']:
                    out.channels[chan['topic']] = chan
        subs = {}
        decoders = {}
        for sub_id, topic in enumerate(topics, start=1):
            chan = out.channels[topic]
            subs[sub_id] = topic
            out.messages[topic] = []
            out.arrivals[topic] = []
            if chan['encoding'] == 'cdr':
                store = ros2msg_store(chan['schemaName'], chan['schema'])
                decoders[sub_id] = (lambda s, n: lambda b: s.deserialize_cdr(b, n))(
                    store, chan['schemaName'])
            else:
                assert chan['encoding'] == 'protobuf', chan
                cls = protobuf_class(chan['schemaName'], chan['schema'])
                decoders[sub_id] = cls.FromString
        await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': i, 'channelId': out.channels[t]['id']} for i, t in subs.items()]}))
        if on_subscribed is not None:
            on_subscribed()
        while not done(out):
            msg = await recv(ws)
            if isinstance(msg, str):
                continue
            arrival = time.time_ns()
            opcode, sub_id, stamp = struct.unpack_from('<BIQ', msg, 0)
            if opcode != 0x01 or sub_id not in subs:
                continue
            out.messages[subs[sub_id]].append((stamp, decoders[sub_id](bytes(msg[13:]))))
            out.arrivals[subs[sub_id]].append(arrival)
    return out
