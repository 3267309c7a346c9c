"""One WebSocket client: its state, its registrations and its bounded outgoing queues.

Outgoing frames wait in per-subscription queues bounded by the subscription's
``queue_length`` (oldest dropped first) and in one control queue for answers.  A single writer
task per session drains them, so a slow client only ever slows itself down: fan-out never
awaits a socket.  Answers are never dropped; a client that lets more than
:data:`CONTROL_QUEUE_LIMIT` answers pile up is disconnected instead (policy violation).
"""

from __future__ import annotations

import asyncio
import enum
import itertools
import json
import logging
import struct
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Union

from websockets.protocol import State

from .protocol import CLOSE_POLICY_VIOLATION, LEVELS, OP_FRAGMENT, OP_STATUS

log = logging.getLogger(__name__)

#: frames waiting to be sent: text, binary, or the fragments of one text message
Frame = Union[str, bytes, list[str]]

CONTROL_QUEUE_LIMIT = 10_000
WRITE_BATCH = 64
DIRECT_WRITE_LIMIT = 64 * 1024
"""Bytes waiting in a socket's buffer above which frames go through the queue and writer."""
DEFAULT_QUEUE_LENGTH = 1000
"""Backlog per subscription when the client gives no ``queue_length`` (or 0)."""

_session_numbers = itertools.count(1)
FIN_TEXT = 0x81
"""First byte of an unfragmented text frame: FIN, no RSV bits, opcode 1 (RFC 6455 5.2)."""
_HEADER_16 = struct.Struct("!BBH")
_HEADER_64 = struct.Struct("!BBQ")


class SessionState(enum.Enum):
    """Where a connection is in its life."""

    AUTHENTICATING = "authenticating"
    """Only an ``auth`` message is accepted (a shared secret is configured)."""
    OPEN = "open"
    """Requests are served."""
    CLOSED = "closed"
    """The socket is gone; late answers are discarded and registrations were released."""


@dataclass
class SubscriptionQueue:
    """Frames of one client subscription not yet written to its socket."""

    limit: int
    frames: deque[Frame] = field(default_factory=deque)
    dropped: int = 0

    def push(self, frame: Frame) -> None:
        if len(self.frames) >= self.limit:
            self.frames.popleft()
            self.dropped += 1
        self.frames.append(frame)


class Session:
    """Per-connection state of the bridge, shared by the op handlers of every module."""

    def __init__(self, websocket: Any, authenticated: bool) -> None:
        self.number = next(_session_numbers)
        self.websocket = websocket
        self.peer = str(getattr(websocket, "remote_address", "?"))
        self.state = SessionState.OPEN if authenticated else SessionState.AUTHENTICATING
        self.status_level = "none"
        self.fragment_size: int | None = None
        self._control: deque[Frame] = deque()
        self._queues: dict[object, SubscriptionQueue] = {}
        self._wake = asyncio.Event()
        self._fragment_ids = itertools.count(1)
        self._writer_idle = False  # True while the writer waits with nothing queued
        self.writer = asyncio.get_running_loop().create_task(self._write(), name=f"session-{self.number}-writer")

    # --- sending -------------------------------------------------------------------------------
    def send(self, message: dict[str, Any]) -> None:
        """Queue an answer (never dropped while the session is open)."""
        self.send_frame(json.dumps(message, separators=(",", ":"), allow_nan=False))

    def send_frame(self, frame: str | bytes, fragment_size: int | None = None) -> None:
        """Queue an encoded answer frame, split into fragments if ``fragment_size`` asks."""
        if self.state is SessionState.CLOSED:
            return
        if len(self._control) >= CONTROL_QUEUE_LIMIT:
            log.warning("session %d: %d answers unread, disconnecting", self.number, len(self._control))
            self.close(CLOSE_POLICY_VIOLATION, "client reads too slowly")
            return
        frame = self._fragmented(frame, fragment_size)
        if not self._write_directly(frame):
            self._control.append(frame)
            self._wake.set()

    def send_topic_frame(self, key: object, frame: str | bytes, queue_length: int, fragment_size: int | None) -> None:
        """Queue a topic message of subscription ``key``, dropping its oldest beyond ``queue_length``."""
        if self.state is SessionState.CLOSED:
            return
        queue = self._queues.get(key)
        if queue is None:
            queue = self._queues[key] = SubscriptionQueue(queue_length or DEFAULT_QUEUE_LENGTH)
        frame = self._fragmented(frame, fragment_size)
        if not self._write_directly(frame):
            queue.push(frame)
            self._wake.set()

    def _write_directly(self, frame: Frame) -> bool:
        """Write ``frame`` at once if nothing waits before it and the socket keeps up; this saves
        the writer task's loop turn on every frame of a client that reads promptly.  A text
        frame is framed here (:func:`_text_frame`), not by websockets' per-frame Python."""
        if not self._writer_idle or self._wake.is_set():
            return False
        websocket = self.websocket
        transport = websocket.transport
        if (websocket.protocol.state is not State.OPEN or transport is None or transport.is_closing()
                or transport.get_write_buffer_size() > DIRECT_WRITE_LIMIT):
            return False
        if isinstance(frame, str):
            if websocket.protocol.writes:  # something websockets queued goes first (a pong)
                websocket.send_data()
            transport.write(_text_frame(frame))
        else:
            _emit(websocket.protocol, frame)
            websocket.send_data()
        return True

    def forget_queue(self, key: object) -> None:
        """Discard the backlog of a subscription that ended."""
        self._queues.pop(key, None)

    def status(self, level: str, text: str, request_id: Any = None) -> None:
        """Send a ``status`` message if the client asked for this level with ``set_level``."""
        if self.status_level == "none" or LEVELS.index(level) < LEVELS.index(self.status_level):
            return
        message: dict[str, Any] = {"op": OP_STATUS, "level": level, "msg": text}
        if request_id is not None:
            message["id"] = request_id
        self.send(message)

    def _fragmented(self, frame: str | bytes, fragment_size: int | None) -> Frame:
        size = fragment_size or self.fragment_size
        if not size or isinstance(frame, bytes) or len(frame) <= size:
            return frame
        fragment_id = f"fragment:{self.number}:{next(self._fragment_ids)}"
        parts = [frame[i:i + size] for i in range(0, len(frame), size)]
        return [
            json.dumps({"op": OP_FRAGMENT, "id": fragment_id, "data": part, "num": num, "total": len(parts)},
                       separators=(",", ":"))
            for num, part in enumerate(parts)
        ]

    async def _write(self) -> None:
        # Frames are handed to the connection's sans-I/O protocol in batches and written with one
        # transport write and one drain per batch: per-frame ``send()`` calls cost more than the
        # JSON encoding of a small message.  ``drain`` waits only while this client's own socket
        # buffer is full, so a slow client pauses only its own writer.
        websocket = self.websocket
        protocol = websocket.protocol
        try:
            while self.state is not SessionState.CLOSED:
                self._writer_idle = True
                await self._wake.wait()
                self._writer_idle = False
                self._wake.clear()
                while True:
                    batch = self._take_batch()
                    if not batch:
                        break
                    if protocol.state is not State.OPEN:
                        return
                    for frame in batch:
                        _emit(protocol, frame)
                    _send_pending(websocket)
                    await websocket.drain()
        except Exception as exc:  # the connection is gone; the reader side cleans up
            log.debug("session %d writer stopped: %s", self.number, exc)
        finally:
            self._writer_idle = False

    def _take_batch(self) -> list[str | bytes]:
        """Up to WRITE_BATCH frames: answers first, then one per subscription in turn (fair
        between topics, FIFO within one)."""
        batch: list[str | bytes] = []
        control = self._control
        while control and len(batch) < WRITE_BATCH:
            _extend(batch, control.popleft())
        progress = True
        while progress and len(batch) < WRITE_BATCH:
            progress = False
            for queue in self._queues.values():
                if queue.frames:
                    _extend(batch, queue.frames.popleft())
                    progress = True
        return batch

    def close(self, code: int, reason: str) -> None:
        """Close the socket from the server side (the reader then releases registrations)."""
        asyncio.get_running_loop().create_task(self.websocket.close(code, reason))

    def mark_closed(self) -> None:
        """Stop queueing and writing; called once when the connection ends."""
        self.state = SessionState.CLOSED
        self._control.clear()
        self._queues.clear()
        self._wake.set()


def _text_frame(text: str) -> bytes:
    """``text`` as one unmasked, uncompressed WebSocket text frame (RFC 6455 5.2), what websockets'
    ``send_text`` makes on this server (no extensions) in a tenth of the Python calls."""
    payload = text.encode()
    size = len(payload)
    if size < 126:
        return bytes((FIN_TEXT, size)) + payload
    if size < 1 << 16:
        return _HEADER_16.pack(FIN_TEXT, 126, size) + payload
    return _HEADER_64.pack(FIN_TEXT, 127, size) + payload


def _emit(protocol: Any, frame: Frame) -> None:
    for part in frame if isinstance(frame, list) else (frame,):
        if isinstance(part, str):
            protocol.send_text(part.encode())
        else:
            protocol.send_binary(part)


def _send_pending(websocket: Any) -> None:
    """Write the frames the protocol holds (a writer batch) with one ``writelines``, a single
    ``writev`` on uvloop: websockets' ``send_data`` writes each frame on its own."""
    if websocket.protocol.state is State.OPEN:  # so no end-of-stream marker is among them
        websocket.transport.writelines(websocket.protocol.data_to_send())
    else:
        websocket.send_data()


def _extend(batch: list[str | bytes], frame: Frame) -> None:
    if isinstance(frame, list):
        batch.extend(frame)
    else:
        batch.append(frame)
