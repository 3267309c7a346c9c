"""Outgoing ``compression`` options of ``subscribe``: png, cbor and cbor-raw.

* ``png``: the JSON text packed as the RGB pixels of a square PNG (padded with newlines), sent
  as ``{"op": "png", "data": <base64>}``, as rosbridge's ``pngcompression`` does.
* ``cbor``: a binary frame holding the CBOR map of the publish message; numeric arrays become
  RFC 8746 typed arrays (little-endian tags 69-86) and ``uint8[]`` a byte string, so large
  arrays cost no per-element encoding.
* ``cbor-raw``: a binary frame whose ``msg`` is ``{secs, nsecs, bytes}`` with the CDR bytes.
"""

from __future__ import annotations

import base64
import math
import struct
import time
import zlib
from typing import Any

import cbor2
from rclpy.serialization import serialize_message

from .protocol import COMPRESSION_CBOR, COMPRESSION_CBOR_RAW, COMPRESSION_PNG, OP_PNG, OP_PUBLISH

#: (numpy dtype kind, item size) -> CBOR typed-array tag (little-endian), RFC 8746
_TYPED_ARRAY_TAGS = {
    ("u", 2): 69,
    ("u", 4): 70,
    ("u", 8): 71,
    ("i", 1): 72,
    ("i", 2): 77,
    ("i", 4): 78,
    ("i", 8): 79,
    ("f", 4): 85,
    ("f", 8): 86,
}
#: array.array type code -> (kind, item size)
_ARRAY_CODES = {
    "b": ("i", 1),
    "B": ("u", 1),
    "h": ("i", 2),
    "H": ("u", 2),
    "i": ("i", 4),
    "I": ("u", 4),
    "l": ("i", 8),
    "L": ("u", 8),
    "q": ("i", 8),
    "Q": ("u", 8),
    "f": ("f", 4),
    "d": ("f", 8),
}


def encode_publish(compression: str, topic: str, message: Any, json_frame: str) -> str | bytes:
    """The frame for a publish of ``message`` on ``topic`` under ``compression``."""
    if compression == COMPRESSION_PNG:
        return f'{{"op":"{OP_PNG}","data":"{png_encode(json_frame.encode("utf-8"))}"}}'
    if compression == COMPRESSION_CBOR:
        return cbor2.dumps({"op": OP_PUBLISH, "topic": topic, "msg": to_cbor_value(message)})
    if compression == COMPRESSION_CBOR_RAW:
        now = time.time_ns()
        raw = {"secs": now // 1_000_000_000, "nsecs": now % 1_000_000_000, "bytes": serialize_message(message)}
        return cbor2.dumps({"op": OP_PUBLISH, "topic": topic, "msg": raw})
    raise ValueError(f"unknown compression {compression!r}")


def png_encode(data: bytes) -> str:
    """Base64 of a square RGB PNG whose pixels are ``data`` padded with ``\\n``."""
    side = max(1, math.ceil(math.sqrt(len(data) / 3)))
    data = data.ljust(side * side * 3, b"\n")
    row = side * 3
    raw = b"".join(b"\x00" + data[y * row : (y + 1) * row] for y in range(side))

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    png = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw, 6))
        + chunk(b"IEND", b"")
    )
    return base64.b64encode(png).decode("ascii")


def png_decode(text: str) -> bytes:
    """The payload of :func:`png_encode` (trailing padding removed); used by tests and tools."""
    png = base64.b64decode(text)
    pos, idat, width = 8, b"", 0
    while pos < len(png):
        length, kind = struct.unpack(">I4s", png[pos : pos + 8])
        body = png[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            width = struct.unpack(">I", body[:4])[0]
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw, row = zlib.decompress(idat), width * 3
    return b"".join(raw[i + 1 : i + 1 + row] for i in range(0, len(raw), row + 1)).rstrip(b"\n")


def to_cbor_value(value: Any) -> Any:
    """A CBOR-ready value of a ROS message field (typed arrays for numeric arrays)."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: to_cbor_value(getattr(value, name)) for name in value.get_fields_and_field_types()}
    typecode = getattr(value, "typecode", None)
    dtype = getattr(value, "dtype", None)
    if typecode is not None or dtype is not None:
        kind_size = (
            _ARRAY_CODES.get(typecode) if typecode else (dtype.kind, dtype.itemsize) if dtype is not None else None
        )
        if kind_size == ("u", 1):
            return bytes(value)
        tag = _TYPED_ARRAY_TAGS.get(kind_size) if kind_size is not None else None
        if tag is not None:
            return cbor2.CBORTag(tag, value.tobytes())
        return [to_cbor_value(v) for v in value.tolist()]
    if isinstance(value, (list, tuple)):
        return [to_cbor_value(v) for v in value]
    if isinstance(value, bytes) and len(value) == 1:  # octet
        return value[0]
    return value
