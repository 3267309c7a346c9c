"""The bridge's own splitting of incoming bytes into WebSocket frames (``BridgeConnection``),
driven over a bare TCP socket with hand-built frames, so every split and oddity is chosen here."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
from collections.abc import Iterator

import pytest

from .rosbridge_support import RawClient

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


def handshake(host: str, port: int) -> bytes:
    key = base64.b64encode(os.urandom(16)).decode()
    return (f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode()


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


@pytest.fixture
def client(bridge: tuple[str, int]) -> Iterator[FrameSocket]:
    connection = FrameSocket(*bridge)
    connection.sock.sendall(text({"op": "set_level", "level": "error"}))
    yield connection
    connection.close()


def unknown_op(request_id: str) -> bytes:
    return text({"op": "teleport", "id": request_id})


def test_frames_split_at_every_byte_are_reassembled(client: FrameSocket) -> None:
    """7-bit, 16-bit and 64-bit payload lengths, each sent one byte per write."""
    for request_id in ("short", "m" * 300, "l" * 70_000):
        call = text({"op": "call_service", "service": "/rosapi/get_ros_version", "id": request_id})
        step = 1 if len(call) < 1000 else 997
        for start in range(0, len(call), step):
            client.sock.sendall(call[start:start + step])
        answer = client.read_message()
        assert (answer["op"], answer["id"], answer["result"]) == ("service_response", request_id, True)


def test_frames_in_one_write_are_answered_in_order_with_control_and_fragmented_frames_among_them(
        client: FrameSocket) -> None:
    fragmented = json.dumps({"op": "teleport", "id": "third"}).encode()
    burst = (unknown_op("first") + frame(PING, b"are you there") + unknown_op("second")
             + frame(TEXT, fragmented[:9], fin=False) + frame(PING, b"mid-message")
             + frame(CONTINUATION, fragmented[9:]) + unknown_op("fourth"))
    client.sock.sendall(burst)
    pongs, ids = [], []
    while len(ids) < 4:
        opcode, payload = client.read_frame()
        if opcode == PONG:
            pongs.append(payload)
        elif opcode == TEXT:
            ids.append(json.loads(payload)["id"])
    assert ids == ["first", "second", "third", "fourth"]
    assert pongs == [b"are you there", b"mid-message"]


@pytest.mark.parametrize("attempt", range(4))
def test_a_frame_begun_along_with_the_handshake_is_served(bridge: tuple[str, int], attempt: int) -> None:
    """A client that starts sending before the 101 answer: websockets already holds part of a
    frame (when the bridge reads it with the request, which the timing of reads decides)."""
    call = text({"op": "call_service", "service": "/rosapi/get_time", "id": f"early {attempt}"})
    early = FrameSocket(*bridge, first=call[:5])
    try:
        early.sock.sendall(call[5:])
        answer = early.read_message()
        assert (answer["id"], answer["result"]) == (f"early {attempt}", True)
        early.sock.sendall(text({"op": "call_service", "service": "/rosapi/get_time", "id": "later"}))
        assert early.read_message()["id"] == "later"
    finally:
        early.close()


@pytest.mark.parametrize("bad, code", [
    (frame(TEXT, b'{"op":"set_level","level":"info"}', masked=False), 1002),
    (frame(TEXT, b'{"op":"set_level","level":"info"}', rsv=4), 1002),
    (frame(TEXT, b'{"op":"teleport","id":"\xff\xfe"}'), 1007),
    (bytes([0x81, 0x80 | 127]) + struct.pack("!Q", 50_000_000) + os.urandom(4), 1009),
    (frame(0x3, b"reserved opcode"), 1002),
], ids=["unmasked", "reserved-bit", "invalid-utf8", "too-big", "reserved-opcode"])
def test_invalid_frames_close_with_the_websocket_code_and_others_are_still_served(
        bridge: tuple[str, int], bad: bytes, code: int) -> None:
    victim = FrameSocket(*bridge)
    try:
        victim.sock.sendall(unknown_op("before") + bad + unknown_op("after"))
        assert victim.close_code() == code
    finally:
        victim.close()
    bystander = RawClient(*bridge)
    try:
        answer = bystander.request({"op": "call_service", "service": "/rosapi/get_time", "id": "ok"}, "service_response")
        assert answer["result"] is True
    finally:
        bystander.close()
