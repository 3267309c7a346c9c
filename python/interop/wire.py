"""The suite's own WebSocket client (RFC 6455 on asyncio streams), recording every frame.

Written here rather than taken from a library because the ``websocket`` profile must send what a
library refuses to (unmasked frames, reserved opcodes, invalid UTF-8, a message split by hand)
and see exactly what the server answers (close codes, pongs), and because every frame a case
exchanged belongs in the report.
"""

from __future__ import annotations

import asyncio
import base64
import hashlib
import os
import ssl
import struct
import time
from dataclasses import dataclass
from urllib.parse import urlsplit

from .outcome import Frame

__all__ = [
    "BINARY",
    "CLOSE",
    "CONTINUATION",
    "PING",
    "PONG",
    "TEXT",
    "Message",
    "Recorder",
    "WebSocket",
    "WireClosed",
    "build_frame",
]

CONTINUATION, TEXT, BINARY, CLOSE, PING, PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
_GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
_MAX_MESSAGE = 256 * 1024 * 1024  # a server's answer larger than this is a fault, not something to buffer
_SHOWN = 4000  # characters of one frame kept in the report


class WireClosed(ConnectionError):
    """The server closed the connection (``code`` None: without a close frame)."""

    def __init__(self, code: int | None, reason: str = "") -> None:
        self.code = code
        self.reason = reason
        super().__init__(f"connection closed by the server (code {code}{', ' + reason if reason else ''})")


@dataclass(frozen=True)
class Message:
    """A whole message the server sent: text (``data`` str) or binary (``data`` bytes)."""

    data: str | bytes


class Recorder:
    """The frames of one case, timed from the case's start, over all its connections."""

    def __init__(self) -> None:
        self.started = time.monotonic()
        self.frames: list[Frame] = []

    def record(self, direction: str, connection: str, text: str) -> None:
        if len(text) > _SHOWN:
            text = f"{text[:_SHOWN]}… ({len(text)} characters)"
        self.frames.append(Frame(direction, round(time.monotonic() - self.started, 4), text, connection))


def _mask(data: bytes, key: bytes) -> bytes:
    """XOR with the 4-byte key, as one big integer (fast enough for the 16 MB of the limits case)."""
    size = len(data)
    if not size:
        return data
    stream = (key * (size // 4 + 1))[:size]
    return (int.from_bytes(data, "little") ^ int.from_bytes(stream, "little")).to_bytes(size, "little")


def build_frame(opcode: int, payload: bytes, *, fin: bool = True, masked: bool = True, rsv: int = 0) -> bytes:
    """One client frame (RFC 6455 section 5.2), masked unless told otherwise."""
    head = bytes([(0x80 if fin else 0) | (rsv & 7) << 4 | (opcode & 0xF)])
    bit = 0x80 if masked else 0
    size = len(payload)
    if size < 126:
        head += bytes([bit | size])
    elif size < 1 << 16:
        head += bytes([bit | 126]) + struct.pack("!H", size)
    else:
        head += bytes([bit | 127]) + struct.pack("!Q", size)
    if not masked:
        return head + payload
    key = os.urandom(4)
    return head + key + _mask(payload, key)


def _describe(opcode: int, payload: bytes) -> str:
    if opcode == TEXT:
        return payload.decode("utf-8", "backslashreplace")
    if opcode == CLOSE:
        code = struct.unpack("!H", payload[:2])[0] if len(payload) >= 2 else None
        return f"<close {code} {payload[2:].decode('utf-8', 'replace')!r}>"
    name = {BINARY: "binary", PING: "ping", PONG: "pong", CONTINUATION: "continuation"}.get(opcode, f"opcode {opcode}")
    return f"<{name} {len(payload)} bytes: {payload[:48].hex()}>"


class WebSocket:
    """One client connection. A reader task collects the server's messages in a queue, answers
    its pings and notes its close; ``receive`` takes the next message or raises ``WireClosed``."""

    def __init__(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, recorder: Recorder, label: str
    ) -> None:
        self._reader = reader
        self._writer = writer
        self.recorder = recorder
        self.label = label
        self._queue: asyncio.Queue[Message | WireClosed] = asyncio.Queue()
        self.pongs: asyncio.Queue[bytes] = asyncio.Queue()
        self.closed: WireClosed | None = None
        self._sent_close = False
        self._awake = asyncio.Event()
        self._awake.set()
        self._task = asyncio.ensure_future(self._read_loop())

    @classmethod
    async def connect(
        cls, url: str, recorder: Recorder, label: str, *, ssl_context: ssl.SSLContext | None = None
    ) -> WebSocket:
        """Open ``ws://`` or ``wss://`` URL and do the opening handshake (raises ConnectionError)."""
        parts = urlsplit(url)
        if parts.scheme not in ("ws", "wss") or not parts.hostname:
            raise ConnectionError(f"not a ws:// or wss:// URL: {url!r}")
        secure = parts.scheme == "wss"
        port = parts.port or (443 if secure else 80)
        context = (ssl_context or ssl.create_default_context()) if secure else None
        reader, writer = await asyncio.open_connection(
            parts.hostname, port, ssl=context, limit=_MAX_MESSAGE, server_hostname=parts.hostname if secure else None
        )
        key = base64.b64encode(os.urandom(16)).decode()
        path = parts.path or "/"
        request = (
            f"GET {path}{'?' + parts.query if parts.query else ''} HTTP/1.1\r\nHost: {parts.hostname}:{port}\r\n"
            f"Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
            "Sec-WebSocket-Version: 13\r\n\r\n"
        )
        writer.write(request.encode())
        head = await reader.readuntil(b"\r\n\r\n")
        lines = head.decode("latin-1").split("\r\n")
        if not lines[0].startswith("HTTP/1.1 101"):
            writer.close()
            raise ConnectionError(f"the server refused the WebSocket upgrade: {lines[0]!r}")
        accept = base64.b64encode(hashlib.sha1((key + _GUID).encode()).digest()).decode()
        headers = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:] if line)}
        if headers.get("sec-websocket-accept") != accept:
            writer.close()
            raise ConnectionError("the server's Sec-WebSocket-Accept does not match the key")
        return cls(reader, writer, recorder, label)

    # --- sending ---------------------------------------------------------------------------------

    async def send_raw(self, data: bytes, description: str) -> None:
        """Write bytes a case built itself (recorded with ``description``)."""
        self.recorder.record("sent", self.label, description)
        self._writer.write(data)
        await self._writer.drain()

    async def send_text(self, text: str) -> None:
        await self.send_raw(build_frame(TEXT, text.encode()), text)

    async def send_fragmented(self, pieces: list[str]) -> None:
        """One text message as several frames: TEXT, then CONTINUATION, FIN on the last."""
        data = b"".join(
            build_frame(TEXT if i == 0 else CONTINUATION, piece.encode(), fin=i == len(pieces) - 1)
            for i, piece in enumerate(pieces)
        )
        await self.send_raw(data, f"<text message in {len(pieces)} frames> {''.join(pieces)}")

    async def ping(self, payload: bytes) -> None:
        await self.send_raw(build_frame(PING, payload), _describe(PING, payload))

    async def close(self, code: int = 1000, timeout: float = 2.0) -> None:
        """The closing handshake (bounded), then the socket is closed whatever happened."""
        try:
            if self.closed is None and not self._sent_close:
                self._sent_close = True
                payload = struct.pack("!H", code)
                await self.send_raw(build_frame(CLOSE, payload), _describe(CLOSE, payload))
                await asyncio.wait_for(asyncio.shield(self._task), timeout)
        except (OSError, TimeoutError, asyncio.IncompleteReadError):
            pass
        finally:
            self._task.cancel()
            self._writer.close()

    async def go_quiet(self, seconds: float) -> None:
        """Read nothing for ``seconds``, as a client behind a link outage: no pongs, and the TCP
        window closes once the kernel's buffers are full, so the server's writes back up."""
        self.recorder.record("sent", self.label, f"<quiet: reading nothing for {seconds:g} s>")
        transport = self._writer.transport
        assert isinstance(transport, asyncio.ReadTransport)  # a socket's transport reads and writes
        self._awake.clear()
        transport.pause_reading()
        try:
            await asyncio.sleep(seconds)
        finally:
            transport.resume_reading()
            self._awake.set()
            self.recorder.record("sent", self.label, "<reading again>")

    # --- receiving -------------------------------------------------------------------------------

    async def receive(self) -> Message:
        """The next whole message; raises ``WireClosed`` once the server closed."""
        item = await self._queue.get()
        if isinstance(item, WireClosed):
            self._queue.put_nowait(item)  # every later receive sees the close too
            raise item
        return item

    async def _read_frame(self) -> tuple[bool, int, bytes]:
        first, second = await self._reader.readexactly(2)
        size = second & 0x7F
        if size == 126:
            size = struct.unpack("!H", await self._reader.readexactly(2))[0]
        elif size == 127:
            size = struct.unpack("!Q", await self._reader.readexactly(8))[0]
        if size > _MAX_MESSAGE:
            raise WireClosed(None, f"the server sent a frame of {size} bytes")
        key = await self._reader.readexactly(4) if second & 0x80 else b""
        payload = await self._reader.readexactly(size)
        return bool(first & 0x80), first & 0x0F, _mask(payload, key) if key else payload

    async def _read_loop(self) -> None:
        parts: list[bytes] = []
        kind = TEXT
        try:
            while True:
                await self._awake.wait()
                fin, opcode, payload = await self._read_frame()
                if opcode == PING:
                    self.recorder.record("received", self.label, _describe(PING, payload))
                    if not self._sent_close:
                        self._writer.write(build_frame(PONG, payload))
                    continue
                if opcode == PONG:
                    self.recorder.record("received", self.label, _describe(PONG, payload))
                    self.pongs.put_nowait(payload)
                    continue
                if opcode == CLOSE:
                    self.recorder.record("received", self.label, _describe(CLOSE, payload))
                    code = struct.unpack("!H", payload[:2])[0] if len(payload) >= 2 else None
                    if not self._sent_close:  # echo it, as RFC 6455 5.5.1 asks
                        self._sent_close = True
                        self._writer.write(build_frame(CLOSE, payload[:2]))
                    self._finish(WireClosed(code, payload[2:].decode("utf-8", "replace")))
                    return
                if opcode in (TEXT, BINARY):
                    kind, parts = opcode, [payload]
                else:
                    parts.append(payload)
                if not fin:
                    continue
                data = b"".join(parts)
                parts = []
                message = Message(data.decode("utf-8", "replace") if kind == TEXT else data)
                self.recorder.record("received", self.label, _describe(kind, data))
                self._queue.put_nowait(message)
        except WireClosed as closed:
            self._finish(closed)
        except (asyncio.IncompleteReadError, OSError):
            self.recorder.record("received", self.label, "<TCP connection closed>")
            self._finish(WireClosed(None, "TCP connection closed without a close frame"))

    def _finish(self, closed: WireClosed) -> None:
        self.closed = closed
        self._queue.put_nowait(closed)
