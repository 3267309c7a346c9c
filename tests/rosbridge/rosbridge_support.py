"""Helpers of the rosbridge tests: awaitable inboxes, graph-matching publish, raw clients
(JSON frames, and hand-built WebSocket frames on a bare socket)."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import re
import socket
import struct
import threading
import time
from collections.abc import Callable
from typing import Any

import roslibpy


class Inbox:
    """Messages received by callbacks, awaitable by count (no sleeps)."""

    def __init__(self) -> None:
        self.items: list[Any] = []
        self._condition = threading.Condition()

    def __call__(self, item: Any) -> None:
        with self._condition:
            self.items.append(item)
            self._condition.notify_all()

    def reached(self, count: int, timeout: float) -> bool:
        """Whether ``count`` items arrived within ``timeout`` (waits on the condition)."""
        with self._condition:
            return self._condition.wait_for(lambda: len(self.items) >= count, timeout)

    def wait_for(
        self, count: int, timeout: float = 20.0, *, counted: Callable[[Any], bool] = lambda _: True
    ) -> list[Any]:
        """All items, once ``count`` of them satisfy ``counted`` (by default: any item)."""

        def enough() -> bool:
            return sum(1 for item in self.items if counted(item)) >= count

        with self._condition:
            self._condition.wait_for(enough, timeout)
            assert enough(), f"got {sum(1 for i in self.items if counted(i))} of {count} messages: {self.items[:5]}"
            return list(self.items)


def publish_until_received(topic: roslibpy.Topic, message: dict[str, Any], inbox: Inbox, timeout: float = 20.0) -> int:
    """Publish ``message`` until ``inbox`` gets something: ROS matches publishers to
    subscribers asynchronously, so the first messages of a new publisher may go nowhere.
    Returns the number of items in the inbox afterwards."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        topic.publish(roslibpy.Message(message))
        if inbox.reached(1, 0.1):
            return len(inbox.items)
    raise AssertionError(f"nothing received on {topic.name} within {timeout} s")


class RawClient:
    """A bare WebSocket client speaking JSON frames (no client library in the way)."""

    def __init__(self, host: str, port: int, **options: Any) -> None:
        from websockets.sync.client import connect

        self._stack = contextlib.ExitStack()
        # An unbounded receive queue: frames the test never reads must not stall the closing handshake.
        options.setdefault("max_queue", None)
        self.connection = self._stack.enter_context(connect(f"ws://{host}:{port}", open_timeout=20, **options))

    def send(self, message: dict[str, Any] | str) -> None:
        self.connection.send(message if isinstance(message, str) else json.dumps(message))

    def receive(self, timeout: float = 20.0) -> dict[str, Any]:
        frame = self.connection.recv(timeout=timeout)
        return json.loads(frame) if isinstance(frame, str) else {"binary": frame}

    def receive_op(self, op: str, timeout: float = 20.0) -> dict[str, Any]:
        """The next message with ``op`` (others are skipped)."""
        deadline = time.monotonic() + timeout
        while True:
            message = self.receive(max(0.01, deadline - time.monotonic()))
            if message.get("op") == op:
                return message

    def request(self, message: dict[str, Any], op: str, timeout: float = 20.0) -> dict[str, Any]:
        self.send(message)
        return self.receive_op(op, timeout)

    def close(self) -> None:
        self._stack.close()


def wait_until_discovered(host: str, port: int, topic: str, service: str, node: str, timeout: float = 30.0) -> None:
    """Ask rosapi until the bridge's view of the ROS graph has ``topic``, ``service`` and ``node``:
    discovery is asynchronous, and the tests must not race it."""
    client = RawClient(host, port)
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            topics = client.request({"op": "call_service", "service": "/rosapi/topics"}, "service_response")
            services = client.request({"op": "call_service", "service": "/rosapi/services"}, "service_response")
            nodes = client.request({"op": "call_service", "service": "/rosapi/nodes"}, "service_response")
            if (
                topic in topics["values"]["topics"]
                and service in services["values"]["services"]
                and node in nodes["values"]["nodes"]
            ):
                return
            threading.Event().wait(0.05)  # between polls of the bridge's graph view
        raise AssertionError(f"the bridge never saw {topic}, {service} and {node}")
    finally:
        client.close()


def bridge_url(process: Any) -> str:
    """The ws:// URL from the bridge's READY line."""
    for line in process.output:
        match = re.match(r"READY bridge (wss?://\S+)", line)
        if match:
            return match.group(1)
    raise AssertionError(f"no READY line with a URL:\n{process.tail()}")


TEXT, BINARY, CONTINUATION, CLOSE, PING, PONG = 0x1, 0x2, 0x0, 0x8, 0x9, 0xA


def frame(opcode: int, payload: bytes, *, fin: bool = True, masked: bool = True, rsv: int = 0) -> bytes:
    """One client frame (RFC 6455 5.2), masked unless told otherwise."""
    head = bytes([(0x80 if fin else 0) | rsv << 4 | opcode])
    size = len(payload)
    bit = 0x80 if masked else 0
    if size < 126:
        head += bytes([bit | size])
    elif size < 1 << 16:
        head += bytes([bit | 126]) + struct.pack("!H", size)
    else:
        head += bytes([bit | 127]) + struct.pack("!Q", size)
    if not masked:
        return head + payload
    mask = os.urandom(4)
    return head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def text(message: dict) -> bytes:
    return frame(TEXT, json.dumps(message).encode())


def handshake(host: str, port: int, headers: str = "") -> bytes:
    """An HTTP upgrade request; ``headers`` are extra header lines, each ending in CRLF."""
    key = base64.b64encode(os.urandom(16)).decode()
    return (
        f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n{headers}\r\n"
    ).encode()


class FrameSocket:
    """A WebSocket client on a plain socket: sends whatever bytes a test builds, reads frames."""

    def __init__(self, host: str, port: int, first: bytes = b"") -> None:
        self.sock = socket.create_connection((host, port), timeout=10)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.sendall(handshake(host, port) + first)
        self.pending = b""
        head = self._read_until(b"\r\n\r\n")
        assert head.startswith(b"HTTP/1.1 101"), head

    def _read_until(self, marker: bytes) -> bytes:
        while marker not in self.pending:
            self._fill()
        head, self.pending = self.pending.split(marker, 1)
        return head

    def _fill(self) -> None:
        chunk = self.sock.recv(65536)
        if not chunk:
            raise ConnectionError("the bridge closed the connection")
        self.pending += chunk

    def _take(self, count: int) -> bytes:
        while len(self.pending) < count:
            self._fill()
        data, self.pending = self.pending[:count], self.pending[count:]
        return data

    def read_frame(self) -> tuple[int, bytes]:
        first, second = self._take(2)
        size = second & 0x7F
        if size == 126:
            size = struct.unpack("!H", self._take(2))[0]
        elif size == 127:
            size = struct.unpack("!Q", self._take(8))[0]
        return first & 0x0F, self._take(size)

    def read_message(self) -> dict:
        """The next text message (pongs and others skipped)."""
        while True:
            opcode, payload = self.read_frame()
            if opcode == TEXT:
                return json.loads(payload)
            assert opcode != CLOSE, f"closed: {payload!r}"

    def close_code(self) -> int:
        """Read up to the server's close frame and return its code."""
        while True:
            opcode, payload = self.read_frame()
            if opcode == CLOSE:
                return struct.unpack("!H", payload[:2])[0]

    def close(self) -> None:
        self.sock.close()
