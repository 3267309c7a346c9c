"""The bridge's own splitting of incoming bytes into WebSocket frames (``BridgeConnection``),
driven over a bare TCP socket with hand-built frames, so every split and oddity is chosen here."""

from __future__ import annotations

import json
import os
import struct
from collections.abc import Iterator

import pytest

from .rosbridge_support import CONTINUATION, PING, PONG, TEXT, FrameSocket, RawClient, frame, text


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
            client.sock.sendall(call[start : start + step])
        answer = client.read_message()
        assert (answer["op"], answer["id"], answer["result"]) == ("service_response", request_id, True)


def test_frames_in_one_write_are_answered_in_order_with_control_and_fragmented_frames_among_them(
    client: FrameSocket,
) -> None:
    fragmented = json.dumps({"op": "teleport", "id": "third"}).encode()
    burst = (
        unknown_op("first")
        + frame(PING, b"are you there")
        + unknown_op("second")
        + frame(TEXT, fragmented[:9], fin=False)
        + frame(PING, b"mid-message")
        + frame(CONTINUATION, fragmented[9:])
        + unknown_op("fourth")
    )
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


@pytest.mark.parametrize(
    "bad, code",
    [
        (frame(TEXT, b'{"op":"set_level","level":"info"}', masked=False), 1002),
        (frame(TEXT, b'{"op":"set_level","level":"info"}', rsv=4), 1002),
        (frame(TEXT, b'{"op":"teleport","id":"\xff\xfe"}'), 1007),
        (bytes([0x81, 0x80 | 127]) + struct.pack("!Q", 50_000_000) + os.urandom(4), 1009),
        (frame(0x3, b"reserved opcode"), 1002),
    ],
    ids=["unmasked", "reserved-bit", "invalid-utf8", "too-big", "reserved-opcode"],
)
def test_invalid_frames_close_with_the_websocket_code_and_others_are_still_served(
    bridge: tuple[str, int], bad: bytes, code: int
) -> None:
    victim = FrameSocket(*bridge)
    try:
        victim.sock.sendall(unknown_op("before") + bad + unknown_op("after"))
        assert victim.close_code() == code
    finally:
        victim.close()
    bystander = RawClient(*bridge)
    try:
        answer = bystander.request(
            {"op": "call_service", "service": "/rosapi/get_time", "id": "ok"}, "service_response"
        )
        assert answer["result"] is True
    finally:
        bystander.close()
