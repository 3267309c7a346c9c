"""The WebSocket connection of one client: frame splitting, byte counts and read flow control.

:class:`BridgeConnection` is websockets' server connection with the bridge's fast path for
incoming text frames (below), a :class:`CountedTransport` that counts the bytes each way and
decides when reading pauses, and a cap on the TCP connections it lets in at all
(:class:`ConnectionGate`).

Reading pauses for three reasons, and resumes only when none is left: websockets' own queue
is full, the client's unsent answers exceed ``read_pause_bytes`` (backpressure: a client that
does not read stops being read), or the bridge has handled :data:`FRAMES_PER_TURN` frames of
this client in one event-loop turn (the rest wait for the next turn, so one client's burst
cannot stall the others, and nothing more is read until they are handled: frames that each cost
an answer, such as pings, never pile up unread faster than they are answered).
"""

from __future__ import annotations

import asyncio
import enum
import logging
from collections.abc import Callable, Iterable
from typing import Any

from websockets.asyncio.server import ServerConnection
from websockets.frames import (  # type: ignore[attr-defined]  # apply_mask: the C version (speedups) when built
    DATA_OPCODES,
    Frame,
    apply_mask,
)
from websockets.protocol import State

from .session import FIN_TEXT, Traffic

log = logging.getLogger(__name__)

FRAMES_PER_TURN = 256
HOLD_BACKLOG = "backlog"
HOLD_TURN = "turn"
HOLD_WEBSOCKETS = "websockets"
_STOPS_FRAMES = frozenset((HOLD_BACKLOG, HOLD_TURN))
"""Holds under which frames already read wait in the buffer too."""


class ConnectionGate:
    """TCP connections let in at once: ``limit`` (twice the WebSocket connections allowed, so
    handshakes in progress fit).  One beyond is dropped before it costs more than its accept."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.open = 0
        self.refused = 0

    def admit(self) -> bool:
        if self.open >= self.limit:
            self.refused += 1
            if self.refused in (1, 10, 100) or self.refused % 1000 == 0:
                log.warning(
                    "refused %d TCP connections so far: %d open (limit %d, twice --max-connections)",
                    self.refused,
                    self.open,
                    self.limit,
                )
            return False
        self.open += 1
        return True

    def leave(self) -> None:
        self.open -= 1


class CountedTransport:
    """The connection's transport as websockets and the bridge see it: counts the bytes written
    and pauses reading while any reason to hold it is set (see the module doc)."""

    def __init__(self, transport: asyncio.Transport, traffic: Traffic, on_release: Callable[[], None]) -> None:
        self._transport = transport
        self._traffic = traffic
        self._on_release = on_release
        self.holds: set[str] = set()

    def write(self, data: bytes | bytearray | memoryview) -> None:
        self._traffic.bytes_sent += len(data)
        self._transport.write(data)

    def writelines(self, chunks: Iterable[bytes | bytearray | memoryview]) -> None:
        listed = list(chunks)
        self._traffic.bytes_sent += sum(map(len, listed))
        self._transport.writelines(listed)

    def is_closing(self) -> bool:  # the hot path's calls, spelled out to skip __getattr__
        return self._transport.is_closing()

    def get_write_buffer_size(self) -> int:
        return self._transport.get_write_buffer_size()

    def pause_reading(self) -> None:
        self.hold(HOLD_WEBSOCKETS, True)

    def resume_reading(self) -> None:
        self.hold(HOLD_WEBSOCKETS, False)

    def hold(self, reason: str, on: bool) -> None:
        before = bool(self.holds)
        if on:
            self.holds.add(reason)
        else:
            self.holds.discard(reason)
        if self._transport.is_closing():
            return
        if self.holds and not before:
            self._transport.pause_reading()
        elif before and not self.holds:
            self._transport.resume_reading()
        if not on and before:
            self._on_release()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._transport, name)


class Framing(enum.Enum):
    """Who splits a connection's incoming bytes into WebSocket frames."""

    HANDSHAKE = "handshake"
    """websockets reads the HTTP upgrade request; the bridge watches for bytes pipelined after it."""
    BRIDGE = "bridge"
    """:meth:`BridgeConnection._receive_frames` splits frames; websockets gets all but plain text frames."""
    WEBSOCKETS = "websockets"
    """websockets parses everything (frames came before the handshake ended, or one it must refuse)."""


class BridgeConnection(ServerConnection):
    """A WebSocket connection that hands complete text messages to the bridge as they arrive.

    websockets parses frames in Python generators (about 8 % of the bridge's busy main thread
    in a py-spy profile of the echo benchmark) and hands each message to the handler task
    through a queue and a task wake-up (about 30 µs of CPU per message here).  Once the
    handshake is done, this connection splits the incoming bytes into frames itself.  A masked, unfragmented
    text frame within the size limit goes straight to :attr:`on_text` (once a session is open
    and nothing waits in websockets' queue, so messages keep their order).  Every other frame
    (control, binary, fragmented, invalid) is handed whole to websockets, whose parser thus
    always sits at a frame boundary and answers it as it would have: pongs, close codes 1002,
    1007 and 1009.

    This leans on websockets 17.4's connection internals (``data_received``, ``process_event``,
    ``connection_made``, ``protocol.state``, ``protocol.max_message_size``), pinned in
    requirements.txt; tests/rosbridge/test_framing.py and test_errors.py show whether an
    upgrade keeps them.
    """

    on_text: Callable[[str], None] | None = None
    on_backlog: Callable[[], None] | None = None
    """Called when the socket's write buffer drained: the session may let reading resume."""
    gate: ConnectionGate | None = None
    on_no_request: Callable[[BridgeConnection], None] | None = None
    """Called when the opening handshake timed out before the client's upgrade request had come:
    otherwise nothing would tell a client that never asked (or whose request was lost) from one
    the bridge never heard from."""
    _queued = 0  # messages put in the queue and not yet read by the handler (see message_read)
    _fragmented = False  # the queue holds the first frames of a fragmented message
    _framing = Framing.HANDSHAKE
    _request_ended = False  # the blank line ending the HTTP request has been received
    _tail = b""  # the last bytes of the request so far, to find its end across reads
    _admitted = False
    _ended = False  # the client's EOF has come, or the connection is lost
    _buffer: bytearray
    counted: CountedTransport

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.traffic = Traffic()
        self.counted = CountedTransport(transport, self.traffic, self._released)  # type: ignore[arg-type]
        self.reading_allowed = asyncio.Event()
        self.reading_allowed.set()
        super().connection_made(self.counted)  # type: ignore[arg-type]
        self._admitted = self.gate is None or self.gate.admit()
        if not self._admitted:
            self.counted.abort()

    async def handshake(self, *args: Any, **kwargs: Any) -> None:
        try:
            await super().handshake(*args, **kwargs)
        except asyncio.CancelledError:  # websockets' --handshake-timeout, or the bridge stopping
            if self.request is None and self.server.is_serving() and self.on_no_request is not None:
                self.on_no_request(self)
            raise

    # Both end websockets' stream: frames a later turn still holds are dropped after them (_handle_frames).
    def eof_received(self) -> None:
        self._ended = True
        super().eof_received()

    def connection_lost(self, exc: Exception | None) -> None:
        self._ended = True
        if self._admitted and self.gate is not None:
            self.gate.leave()
            self._admitted = False
        super().connection_lost(exc)

    def hold_reading(self, on: bool) -> None:
        """Stop (or resume) reading this client's requests because of its unsent backlog."""
        if on != (HOLD_BACKLOG in self.counted.holds):
            self.counted.hold(HOLD_BACKLOG, on)
            if on:
                self.reading_allowed.clear()
            else:
                self.reading_allowed.set()

    def _released(self) -> None:
        # A hold ended: frames read before it may wait in the buffer.
        if self._framing is Framing.BRIDGE and not self.counted.holds & _STOPS_FRAMES:
            self.loop.call_soon(self._receive_frames, b"")

    def resume_writing(self) -> None:
        super().resume_writing()
        if self.on_backlog is not None:
            self.on_backlog()

    def data_received(self, data: bytes) -> None:
        self.traffic.bytes_received += len(data)
        if self._framing is Framing.BRIDGE:
            self._receive_frames(data)
        else:
            if self._framing is Framing.HANDSHAKE:
                if self.protocol.state is State.OPEN:
                    self._framing = Framing.BRIDGE
                    self._buffer = bytearray()
                    self._receive_frames(data)
                    return
                self._watch_request(data)
            super().data_received(data)
        if self.on_backlog is not None:
            self.on_backlog()  # a pong or an answer may have filled the socket buffer

    def _watch_request(self, data: bytes) -> None:
        """Leave framing to websockets if bytes follow the HTTP request before the handshake
        ends: its parser may already hold part of a frame.  Clients wait for the 101 answer."""
        if self._request_ended:
            self._framing = Framing.WEBSOCKETS
            return
        joined = self._tail + data
        end = joined.find(b"\r\n\r\n")
        if end < 0:
            self._tail = joined[-3:]
            return
        self._request_ended = True
        if end + 4 < len(joined):
            self._framing = Framing.WEBSOCKETS

    def _receive_frames(self, data: bytes) -> None:
        self._buffer += data
        if self.counted.holds & _STOPS_FRAMES:
            return  # taken up again when the hold ends (_released)
        self._handle_frames()

    def _next_turn(self) -> None:
        """Handle the frames a turn left in the buffer, still without reading more: the socket is
        read again only once they are handled, so a burst of frames that each cost an answer (pings)
        never piles up here faster than it is answered."""
        if HOLD_TURN not in self.counted.holds:
            return
        if HOLD_BACKLOG in self.counted.holds or self._framing is not Framing.BRIDGE:
            self._end_turn()  # the answers are not taken (that hold decides), or websockets frames now
            return
        self._handle_frames()
        if self.on_backlog is not None:
            self.on_backlog()

    def _handle_frames(self) -> None:
        buffer = self._buffer
        size = len(buffer)
        offset = 0
        handled = 0
        next_turn = False
        protocol = self.protocol
        on_text = self.on_text
        while size - offset >= 2:
            second = buffer[offset + 1]
            length = second & 0x7F
            start = offset + 2
            if length == 126:
                if size - start < 2:
                    break
                length = int.from_bytes(buffer[start : start + 2], "big")
                start += 2
            elif length == 127:
                if size - start < 8:
                    break
                length = int.from_bytes(buffer[start : start + 8], "big")
                start += 8
            if (
                protocol.state is not State.OPEN
                or not second & 0x80
                or (protocol.max_message_size is not None and length > protocol.max_message_size)
            ):
                # closing, an unmasked frame, or one too big: websockets takes over and refuses it
                self._framing = Framing.WEBSOCKETS
                rest = bytes(buffer[offset:])
                buffer.clear()
                self._end_turn()
                if not self._ended:  # after the stream's end, websockets takes no more bytes
                    super().data_received(rest)
                return
            end = start + 4 + length
            if end > size:
                break
            text: str | None = None
            if buffer[offset] == FIN_TEXT and on_text is not None and not self._queued and not self._fragmented:
                try:  # noqa: SIM105 (per frame: contextlib.suppress would add a call to the hot path)
                    text = apply_mask(buffer[start + 4 : end], buffer[start : start + 4]).decode()
                except UnicodeDecodeError:
                    pass  # websockets closes the connection with 1007
            if text is not None and on_text is not None:
                on_text(text)
            else:
                super().data_received(bytes(buffer[offset:end]))
            offset = end
            handled += 1
            if HOLD_BACKLOG in self.counted.holds:
                break  # the client's answers pile up: read on once they are sent
            if handled >= FRAMES_PER_TURN and size - offset >= 2:
                next_turn = True
                self.counted.hold(HOLD_TURN, True)  # the rest in the next turn (_next_turn), unread meanwhile
                self.loop.call_soon(self._next_turn)
                break
        del buffer[:offset]
        if not next_turn:
            self._end_turn()

    def _end_turn(self) -> None:
        """The frames read are handled (or another hold stops them): reading may go on."""
        if HOLD_TURN in self.counted.holds:
            self.counted.hold(HOLD_TURN, False)

    def process_event(self, event: Any) -> None:
        if isinstance(event, Frame) and event.opcode in DATA_OPCODES:
            self._fragmented = not event.fin
            if event.fin:
                self._queued += 1
        super().process_event(event)

    def message_read(self) -> None:
        """The handler took one message from the queue."""
        self._queued -= 1
