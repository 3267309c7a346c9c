"""Outgoing compression: png, cbor (typed arrays) and cbor-raw (CDR bytes), on request only."""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator

import cbor2
import pytest

from bridge.rosbridge.compression import png_decode

from .rosbridge_support import RawClient


@pytest.fixture
def raw(bridge: tuple[str, int]) -> Iterator[RawClient]:
    client = RawClient(*bridge)
    yield client
    client.close()


def publish_latched(raw: RawClient, topic: str, type_: str, msg: dict) -> None:
    raw.send({"op": "advertise", "topic": topic, "type": type_, "latch": True})
    raw.send({"op": "publish", "topic": topic, "msg": msg})


def test_png_compression_carries_the_json_message(raw: RawClient) -> None:
    raw.send({"op": "subscribe", "topic": "/peer/latched", "compression": "png"})
    frame = raw.receive_op("png")
    assert json.loads(png_decode(frame["data"])) == {
        "op": "publish",
        "topic": "/peer/latched",
        "msg": {"data": "latched value"},
    }


def test_cbor_uses_typed_arrays_and_byte_strings(raw: RawClient) -> None:
    topic = "/bridge_test/cbor_image"
    publish_latched(raw, topic, "sensor_msgs/Image", {"width": 2, "data": [5, 6, 7]})
    publish_latched(raw, "/bridge_test/cbor_floats", "std_msgs/Float64MultiArray", {"data": [1.5, -2.0]})
    raw.send({"op": "subscribe", "topic": topic, "compression": "cbor"})
    image = cbor2.loads(raw.receive()["binary"])
    assert image["op"] == "publish" and image["topic"] == topic
    assert image["msg"]["data"] == bytes([5, 6, 7]) and image["msg"]["width"] == 2
    raw.send({"op": "subscribe", "topic": "/bridge_test/cbor_floats", "compression": "cbor"})
    floats = cbor2.loads(raw.receive()["binary"])["msg"]["data"]
    assert floats.tag == 86 and struct.unpack("<2d", floats.value) == (1.5, -2.0)


def test_cbor_raw_carries_cdr_bytes(raw: RawClient) -> None:
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import String

    raw.send({"op": "subscribe", "topic": "/peer/latched", "compression": "cbor-raw"})
    message = cbor2.loads(raw.receive()["binary"])["msg"]
    assert set(message) == {"secs", "nsecs", "bytes"}
    assert deserialize_message(message["bytes"], String).data == "latched value"


def test_unknown_compression_is_refused(raw: RawClient) -> None:
    raw.send({"op": "set_level", "level": "error"})
    status = raw.request({"op": "subscribe", "id": "z", "topic": "/peer/latched", "compression": "zip"}, "status")
    assert "compression must be one of none, png, cbor, cbor-raw" in status["msg"]
