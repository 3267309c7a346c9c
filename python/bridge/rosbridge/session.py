"""One WebSocket client: its state, its counters, its log and its bounded outgoing queues.

Outgoing frames wait in per-subscription queues bounded by the subscription's ``queue_length``
(oldest dropped first) and in one queue for answers, all counted in bytes.  A single writer
task per session drains them, so a slow client only ever slows itself down: fan-out never
awaits a socket.  Bounds (:class:`.limits.Limits`):

* above ``read_pause_bytes`` waiting, the bridge stops reading the client's requests until
  they are sent (backpressure: a client that does not read cannot make the bridge buffer
  answers, pongs included, without end);
* above ``max_queued_bytes``, topic messages are dropped oldest first, and an answer (never
  dropped) closes the connection with 1008 instead;
* above ``max_total_queued_bytes`` for all clients together, the client with the most waiting
  is closed with 1008, so the others are not affected.
"""

from __future__ import annotations

import asyncio
import enum
import itertools
import logging
import struct
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import orjson
from websockets.protocol import State

from .limits import Limits
from .protocol import CLOSE_POLICY_VIOLATION, LEVELS, MAX_TEXT, OP_FRAGMENT, OP_STATUS, client_text

log = logging.getLogger(__name__)

#: frames waiting to be sent: text, binary, or the fragments of one text message
Frame = str | bytes | list[str]

WRITE_BATCH = 64
WRITE_BATCH_BYTES = 256 * 1024
"""A writer batch ends at this many frames or bytes, so a batch never floods the socket buffer."""
DIRECT_WRITE_LIMIT = 64 * 1024
"""Bytes waiting in a socket's buffer above which frames go through the queue and writer."""
DEFAULT_QUEUE_LENGTH = 1000
"""Backlog per subscription when the client gives no ``queue_length`` (or 0)."""
LOG_BURST = 20
LOG_PER_S = 0.5
"""A client's log lines: a burst of 20, then one every 2 s; the rest are counted and reported."""

_session_numbers = itertools.count(1)
_fragment_ids = itertools.count(1)
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
    """The socket is gone or being closed; late answers are discarded and registrations released."""


@dataclass
class Traffic:
    """What crossed one connection (WebSocket bytes, TLS overhead not included)."""

    started: float = field(default_factory=time.monotonic)
    bytes_received: int = 0
    bytes_sent: int = 0
    messages_received: int = 0
    messages_sent: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {
            "connected_s": round(time.monotonic() - self.started, 3),
            "bytes_received": self.bytes_received,
            "bytes_sent": self.bytes_sent,
            "messages_received": self.messages_received,
            "messages_sent": self.messages_sent,
        }


class ClientLog:
    """Log lines about one client: truncated, and rate-limited so a client sending garbage
    cannot grow the bridge's log faster than :data:`LOG_PER_S` lines a second."""

    def __init__(self, prefix: str) -> None:
        self.prefix = prefix
        self._tokens = float(LOG_BURST)
        self._last = time.monotonic()
        self.suppressed = 0

    def __call__(self, level: int, text: str, exc_info: BaseException | None = None) -> None:
        now = time.monotonic()
        self._tokens = min(LOG_BURST, self._tokens + (now - self._last) * LOG_PER_S)
        self._last = now
        if self._tokens < 1:
            self.suppressed += 1
            return
        self._tokens -= 1
        note = f" ({self.suppressed} more lines about this client were not logged)" if self.suppressed else ""
        self.suppressed = 0
        log.log(level, "%s: %s%s", self.prefix, client_text(text, MAX_TEXT), note, exc_info=exc_info)


class OutputBudget:
    """Bytes waiting to be sent to all clients together (``max_total_queued_bytes``)."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.total = 0
        self.sessions: set[Session] = set()

    def changed(self, amount: int) -> None:
        self.total += amount
        while self.total > self.limit:
            largest = max(self.sessions, key=lambda s: s.queued, default=None)
            if largest is None or largest.queued == 0:
                return
            largest.cut_off(
                f"the bridge's output buffers are full and this client has the most waiting "
                f"({largest.queued} bytes; --max-total-queued-bytes)"
            )


@dataclass
class SubscriptionQueue:
    """Frames of one client subscription not yet written to its socket, with their sizes."""

    limit: int
    frames: deque[tuple[Frame, int]] = field(default_factory=deque)
    size: int = 0
    dropped: int = 0


class Session:
    """Per-connection state of the bridge, shared by the op handlers of every module."""

    def __init__(
        self, websocket: Any, authenticated: bool, limits: Limits | None = None, budget: OutputBudget | None = None
    ) -> None:
        self.number = next(_session_numbers)
        self.websocket = websocket
        address = getattr(websocket, "remote_address", None)
        self.peer = f"{address[0]}:{address[1]}" if isinstance(address, tuple) else "?"
        self.state = SessionState.OPEN if authenticated else SessionState.AUTHENTICATING
        self.limits = limits or Limits()
        self.budget = budget or OutputBudget(self.limits.max_total_queued_bytes)
        self.budget.sessions.add(self)
        self.status_level: str | None = None
        """What ``set_level`` asked for; None until it was sent (then only refusals are reported)."""
        self.fragment_size: int | None = None
        self.traffic: Traffic = getattr(websocket, "traffic", None) or Traffic()  # the connection counts bytes
        self.log = ClientLog(f"client {self.number}")
        self.queued = 0
        """Bytes in this session's queues (not yet handed to the socket)."""
        self._control: deque[tuple[Frame, int]] = deque()
        self._queues: dict[object, SubscriptionQueue] = {}
        self._wake = asyncio.Event()
        self._writer_idle = False  # True while the writer waits with nothing queued
        self.writer = asyncio.get_running_loop().create_task(self._write(), name=f"session-{self.number}-writer")

    # --- sending -------------------------------------------------------------------------------
    def send(self, message: dict[str, Any]) -> None:
        """Queue an answer (never dropped while the session is open)."""
        self.send_frame(encode(message))

    def send_frame(self, frame: str | bytes, fragment_size: int | None = None) -> None:
        """Queue an encoded answer frame, split into fragments if ``fragment_size`` asks."""
        if self.state is SessionState.CLOSED:
            return
        parts = fragmented(frame, fragment_size or self.fragment_size)
        self.traffic.messages_sent += 1
        if self._write_directly(parts):
            return
        size = frame_size(parts)
        if self.queued + size > self.limits.max_queued_bytes:
            self.cut_off(
                f"client reads too slowly: {self.queued + size} bytes of answers waiting "
                f"(--max-queued-bytes {self.limits.max_queued_bytes})"
            )
            return
        self._control.append((parts, size))
        self._grew(size)

    def send_topic_frame(self, key: object, frame: Frame, queue_length: int) -> None:
        """Queue a topic message of subscription ``key`` (already fragmented if asked), dropping
        its oldest beyond ``queue_length`` and the oldest of any beyond ``max_queued_bytes``."""
        if self.state is SessionState.CLOSED:
            return
        self.traffic.messages_sent += 1
        if self._write_directly(frame):
            return
        queue = self._queues.get(key)
        if queue is None:
            queue = self._queues[key] = SubscriptionQueue(queue_length or DEFAULT_QUEUE_LENGTH)
        size = frame_size(frame)
        freed = 0
        if len(queue.frames) >= queue.limit:
            freed += self._drop_oldest(queue)
        while self.queued - freed + size > self.limits.max_queued_bytes:
            fullest = max(self._queues.values(), key=lambda q: q.size)
            if not fullest.frames:
                break
            freed += self._drop_oldest(fullest)
        self.queued -= freed
        self.budget.changed(-freed)
        if self.queued + size > self.limits.max_queued_bytes:  # larger than the whole allowance
            queue.dropped += 1
            self.log(logging.WARNING, f"dropped a {size}-byte message larger than --max-queued-bytes")
            return
        queue.frames.append((frame, size))
        queue.size += size
        self._grew(size)

    @staticmethod
    def _drop_oldest(queue: SubscriptionQueue) -> int:
        _, size = queue.frames.popleft()
        queue.size -= size
        queue.dropped += 1
        return size

    def _grew(self, size: int) -> None:
        self.queued += size
        self._wake.set()
        self.budget.changed(size)
        if self.state is not SessionState.CLOSED:
            self.backlog_changed()

    def backlog_changed(self) -> None:
        """Hold or release reading from the client as its unsent bytes cross ``read_pause_bytes``."""
        hold = getattr(self.websocket, "hold_reading", None)
        if hold is None:
            return
        transport = self.websocket.transport
        backlog = self.queued + (transport.get_write_buffer_size() if transport is not None else 0)
        if backlog > self.limits.read_pause_bytes:
            hold(True)
        elif backlog <= self.limits.read_pause_bytes // 2:
            hold(False)

    def _write_directly(self, frame: Frame) -> bool:
        """Write ``frame`` at once if nothing waits before it and the socket keeps up; this saves
        the writer task's loop turn on every frame of a client that reads promptly.  A text
        frame is framed here (:func:`_text_frame`), not by websockets' per-frame Python."""
        if not self._writer_idle or self._wake.is_set():
            return False
        websocket = self.websocket
        transport = websocket.transport
        if (
            websocket.protocol.state is not State.OPEN
            or transport is None
            or transport.is_closing()
            or transport.get_write_buffer_size() > DIRECT_WRITE_LIMIT
        ):
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
        queue = self._queues.pop(key, None)
        if queue is not None and queue.size:
            self.queued -= queue.size
            self.budget.changed(-queue.size)

    def status(self, level: str, text: str, request_id: Any = None, *, always: bool = False) -> None:
        """Send a ``status`` message if the client asked for this level with ``set_level``
        (or, with ``always``, unless it asked for none at all)."""
        asked = self.status_level
        if asked is None:
            if not always:
                return
        elif asked == "none" or LEVELS.index(level) < LEVELS.index(asked):
            return
        message: dict[str, Any] = {"op": OP_STATUS, "level": level, "msg": text}
        if request_id is not None:
            message["id"] = request_id
        self.send(message)

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
                    self.backlog_changed()
        except Exception as exc:  # the connection is gone; the reader side cleans up
            log.debug("session %d writer stopped: %s", self.number, exc)
        finally:
            self._writer_idle = False

    def _take_batch(self) -> list[str | bytes]:
        """Up to WRITE_BATCH frames or WRITE_BATCH_BYTES: answers first, then one per
        subscription in turn (fair between topics, FIFO within one)."""
        batch: list[str | bytes] = []
        taken = 0
        control = self._control
        while control and len(batch) < WRITE_BATCH and taken < WRITE_BATCH_BYTES:
            frame, size = control.popleft()
            taken += size
            _extend(batch, frame)
        progress = True
        while progress and len(batch) < WRITE_BATCH and taken < WRITE_BATCH_BYTES:
            progress = False
            for queue in self._queues.values():
                if queue.frames:
                    frame, size = queue.frames.popleft()
                    queue.size -= size
                    taken += size
                    _extend(batch, frame)
                    progress = True
        if taken:
            self.queued -= taken
            self.budget.changed(-taken)
        return batch

    def cut_off(self, reason: str) -> None:
        """Close a client that cannot keep up (1008) and free what waits for it at once."""
        if self.state is SessionState.CLOSED:
            return
        self.log(logging.WARNING, f"closing the connection: {reason}")
        self.mark_closed()
        self.close(CLOSE_POLICY_VIOLATION, "client reads too slowly")

    def close(self, code: int, reason: str) -> None:
        """Close the socket from the server side (the reader then releases registrations)."""
        asyncio.get_running_loop().create_task(self.websocket.close(code, reason))

    def mark_closed(self) -> None:
        """Stop queueing and writing; called when the connection ends or is cut off."""
        self.state = SessionState.CLOSED
        self._control.clear()
        self._queues.clear()
        self.budget.changed(-self.queued)
        self.budget.sessions.discard(self)
        self.queued = 0
        self._wake.set()


def encode(message: dict[str, Any]) -> str:
    """JSON text of an answer built from checked values (:func:`.protocol.echo` and
    :func:`.protocol.client_text` for anything a client sent); NaN/Inf become null."""
    return orjson.dumps(message).decode()


def fragmented(frame: str | bytes, size: int | None) -> Frame:
    """``frame`` as rosbridge ``fragment`` messages of ``size`` characters, if it is longer."""
    if not size or isinstance(frame, bytes) or len(frame) <= size:
        return frame
    fragment_id = f"fragment:{next(_fragment_ids)}"
    total = (len(frame) + size - 1) // size
    return [
        orjson.dumps(
            {"op": OP_FRAGMENT, "id": fragment_id, "data": frame[i * size : (i + 1) * size], "num": i, "total": total}
        ).decode()
        for i in range(total)
    ]


def frame_size(frame: Frame) -> int:
    """Bytes a queued frame holds (characters for text: the JSON is mostly ASCII)."""
    return sum(map(len, frame)) if isinstance(frame, list) else len(frame)


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
