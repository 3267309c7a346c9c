"""The robot camera's image beside the 3D view: a rosbridge ``sensor_msgs/Image`` as a PNG.

The simulation publishes ``camera/<name>/image`` (rgb8, about once a second, only while someone
subscribes); the ground feed asks for it throttled and keeps the newest as PNG bytes for the
page. Which camera: the one the server watches (``caretaker serve --camera``) when the scene
has it, else the scene's first (``camera/<name>`` frames on ``sim/frames``), so IVA shows its
rack camera and EVA its arm's camera. The image from outside is checked before use.
"""

from __future__ import annotations

import base64
import binascii
import struct
import zlib
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["CameraImageError", "choose_camera", "png_from_image"]

CAMERA_FRAME_PREFIX = "camera/"
MAX_PIXELS = 4096 * 4096


class CameraImageError(ValueError):
    """An image message that cannot be shown; the message says which field is wrong."""


def choose_camera(frame_names: Iterable[str], preferred: str | None) -> str | None:
    """The camera to show, from the names on ``sim/frames``; None if the scene has none."""
    cameras = [n[len(CAMERA_FRAME_PREFIX) :] for n in frame_names if n.startswith(CAMERA_FRAME_PREFIX)]
    if preferred in cameras:
        return preferred
    return cameras[0] if cameras else None


def png_from_image(msg: Mapping[str, Any]) -> bytes:
    """PNG bytes of an rgb8 (or rgba8/mono8) image message as rosbridge sends it (data in base64)."""
    encodings = {"rgb8": (2, 3), "rgba8": (6, 4), "mono8": (0, 1)}
    encoding = str(msg.get("encoding", ""))
    if encoding not in encodings:
        raise CameraImageError(f"image.encoding: {encoding!r} is not one of {', '.join(encodings)}")
    colour, channels = encodings[encoding]
    width, height, step = (_positive(msg.get(k), f"image.{k}") for k in ("width", "height", "step"))
    if width * height > MAX_PIXELS:
        raise CameraImageError(f"image: {width}x{height} is more than {MAX_PIXELS} pixels")
    try:
        data = base64.b64decode(str(msg.get("data", "")), validate=True)
    except (binascii.Error, ValueError):
        raise CameraImageError("image.data: not base64") from None
    if step < width * channels or len(data) < step * height:
        raise CameraImageError(f"image.data: {len(data)} bytes for {height} rows of {step}")
    rows = b"".join(b"\x00" + data[r * step : r * step + width * channels] for r in range(height))

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, colour, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 6)) + chunk(b"IEND", b"")


def _positive(value: Any, where: str) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value <= 0:
        raise CameraImageError(f"{where}: expected a positive integer, got {value!r}")
    return value
