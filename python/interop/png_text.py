"""Reading the text a rosbridge ``png`` message carries (P-CMP-1): a minimal PNG decoder.

The server puts the JSON text of a message into the pixel bytes of an 8-bit PNG and pads it
with newlines; this undoes the five PNG row filters and returns the bytes. Anything that is not
such a PNG raises ``ValueError`` with what is wrong (the input comes from the server under test).
"""

from __future__ import annotations

import struct
import zlib

__all__ = ["png_bytes"]

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}  # colour type -> bytes per pixel at bit depth 8


def _paeth(left: int, up: int, corner: int) -> int:
    estimate = left + up - corner
    to_left, to_up, to_corner = abs(estimate - left), abs(estimate - up), abs(estimate - corner)
    if to_left <= to_up and to_left <= to_corner:
        return left
    return up if to_up <= to_corner else corner


def png_bytes(data: bytes) -> bytes:
    """The pixel bytes of an 8-bit grey, grey+alpha, RGB or RGBA PNG, rows concatenated."""
    if not data.startswith(_SIGNATURE):
        raise ValueError("not a PNG (signature missing)")
    position, header, compressed = len(_SIGNATURE), b"", []
    while position + 8 <= len(data):
        size, kind = struct.unpack("!I4s", data[position : position + 8])
        body = data[position + 8 : position + 8 + size]
        if len(body) != size:
            raise ValueError("a PNG chunk is cut short")
        if kind == b"IHDR":
            header = body
        elif kind == b"IDAT":
            compressed.append(body)
        elif kind == b"IEND":
            break
        position += 12 + size
    if len(header) != 13:
        raise ValueError("the PNG has no IHDR chunk")
    width, height, depth, colour, _, _, interlace = struct.unpack("!IIBBBBB", header)
    if depth != 8 or colour not in _CHANNELS or interlace:
        raise ValueError(f"unsupported PNG: depth {depth}, colour type {colour}, interlace {interlace}")
    step = _CHANNELS[colour]
    stride = width * step
    raw = zlib.decompress(b"".join(compressed))
    if len(raw) != height * (stride + 1):
        raise ValueError(f"the PNG data holds {len(raw)} bytes, not {height} rows of {stride + 1}")
    rows: list[bytearray] = []
    previous = bytearray(stride)
    for row_index in range(height):
        start = row_index * (stride + 1)
        kind, row = raw[start], bytearray(raw[start + 1 : start + 1 + stride])
        for i in range(stride):
            left = row[i - step] if i >= step else 0
            up = previous[i]
            corner = previous[i - step] if i >= step else 0
            if kind == 1:
                row[i] = (row[i] + left) & 0xFF
            elif kind == 2:
                row[i] = (row[i] + up) & 0xFF
            elif kind == 3:
                row[i] = (row[i] + (left + up) // 2) & 0xFF
            elif kind == 4:
                row[i] = (row[i] + _paeth(left, up, corner)) & 0xFF
            elif kind != 0:
                raise ValueError(f"unknown PNG row filter {kind}")
        rows.append(row)
        previous = row
    return b"".join(rows)
