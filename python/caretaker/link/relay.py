"""The link emulator: a TCP relay that makes a local connection behave like a long, lossy link.

It accepts connections on the ground side and opens one to the target (the habitat's
rosbridge) for each. Every segment of bytes waits for the line (bandwidth shared by all
connections of a direction, headers counted), then for its one-way delay plus jitter plus the
stall of its lost transmissions (tcp_model.py), and is delivered in order. Opening a connection
costs what a TCP handshake costs: the target sees it one uplink delay later, and the client's
first bytes leave only after a round trip.

Outages: a hold stops every sender for its length (bytes already on their way still arrive);
a reset sends RST to both ends of every connection and refuses new ones for its length.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import os
import socket
import struct
from collections.abc import Awaitable
from dataclasses import dataclass
from typing import TypeVar

from .model import SEGMENT_OVERHEAD, Direction, LinkConfig, Outage, OutageKind
from .stats import ConnectionStats, LinkStats
from .tcp_model import TcpModel

__all__ = ["LinkEmulator", "TargetUnreachable"]

log = logging.getLogger("caretaker.link")

_READ_SIZE = 65_536
_Streams = asyncio.Future[tuple[asyncio.StreamReader, asyncio.StreamWriter]]
_T = TypeVar("_T")


class TargetUnreachable(OSError):
    """The relay could not connect to its target; the client's connection is reset."""


class _PeerReset(Exception):
    """One end reset its connection; the reset has crossed the link and ends the other end too."""


@dataclass(frozen=True)
class _Arrival:
    """Bytes (or, with ``data`` None, the sender's FIN or RST) due at the far end at ``at``."""

    at: float
    data: bytes | None
    reset: bool = False


class _Line:
    """The shared line of one direction: segments are serialised one after another at its rate."""

    def __init__(self, seconds_per_byte: float) -> None:
        self._seconds_per_byte = seconds_per_byte
        self._free_at = 0.0

    def reserve(self, nbytes: int, now: float) -> float:
        """Book the line for ``nbytes``; return when their last bit is sent."""
        self._free_at = max(now, self._free_at) + nbytes * self._seconds_per_byte
        return self._free_at


def _send_reset(writer: asyncio.StreamWriter) -> None:
    """Close with RST rather than FIN (SO_LINGER 0), as a peer that lost the connection does."""
    sock = writer.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    writer.transport.abort()


class LinkEmulator:
    """Relay connections from ``listen`` to ``target`` through an emulated link.

    Use as ``async with LinkEmulator(config, listen=("127.0.0.1", 0), target=(...)) as link:``;
    :attr:`address` is the bound address. :meth:`hold` and :meth:`reset` start outages at run
    time; the config's scheduled outages start relative to :meth:`start`.
    """

    def __init__(self, config: LinkConfig, *, listen: tuple[str, int], target: tuple[str, int]) -> None:
        self.config = config
        self.listen = listen
        self.target = target
        self.model = TcpModel(config)
        seconds_per_byte = {d: config.direction(d).serialisation(1) for d in Direction}
        self._lines = {d: _Line(seconds_per_byte[d]) for d in Direction}
        self._ids = itertools.count(1)
        self._connections: list[ConnectionStats] = []
        self._tasks: dict[int, asyncio.Task[None]] = {}
        self._server: asyncio.Server | None = None
        self._scheduled: list[asyncio.TimerHandle] = []
        self._started_at = 0.0
        self._hold_until = 0.0
        self._refuse_until = 0.0
        self._holds = self._resets = self._refused = 0

    # ---- lifecycle -------------------------------------------------------------------------------

    async def start(self) -> None:
        """Listen, and schedule the config's outages from now.

        Raises:
            OSError: the listen address cannot be bound.
        """
        loop = asyncio.get_running_loop()
        self._server = await asyncio.start_server(self._accept, *self.listen)
        self._started_at = loop.time()
        self._scheduled = [loop.call_later(outage.at, self.outage, outage) for outage in self.config.outages]
        log.info("link %s:%d -> %s:%d: %s", *self.address, *self.target, self.config.describe())

    @property
    def address(self) -> tuple[str, int]:
        """The address the link listens on (the real port when 0 was asked)."""
        if self._server is None:
            raise RuntimeError("the link is not started")
        host, port = self._server.sockets[0].getsockname()[:2]
        return host, port

    async def close(self) -> None:
        """Stop listening and reset every connection still open."""
        for handle in self._scheduled:
            handle.cancel()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
        await self._end_all("link closed")

    async def wait_idle(self) -> None:
        """Return once no connection is open (each has been counted as closed in :meth:`stats`)."""
        while self._tasks:
            await asyncio.gather(*self._tasks.values(), return_exceptions=True)

    async def __aenter__(self) -> LinkEmulator:
        await self.start()
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.close()

    # ---- outages and stats -------------------------------------------------------------------------

    def outage(self, outage: Outage) -> None:
        """Start ``outage`` now (its ``at`` is the caller's business)."""
        if outage.kind is OutageKind.HOLD:
            self.hold(outage.seconds)
        else:
            self.reset(outage.seconds)

    def hold(self, seconds: float) -> None:
        """Send nothing either way for ``seconds``; connections stay up and bytes arrive after."""
        now = self._now()
        self._hold_until = max(self._hold_until, now + seconds)
        self._holds += 1
        log.warning("outage: holding all traffic for %g s", seconds)
        asyncio.get_running_loop().call_at(self._hold_until, self._outage_over, "hold")

    def reset(self, seconds: float) -> None:
        """Reset every connection now and refuse new ones for ``seconds``."""
        self._refuse_until = max(self._refuse_until, self._now() + seconds)
        self._resets += 1
        log.warning("outage: resetting %d connection(s), refusing new ones for %g s", len(self._tasks), seconds)
        asyncio.get_running_loop().call_at(self._refuse_until, self._outage_over, "reset")
        for task in self._tasks.values():
            task.cancel("reset by outage")

    def _outage_over(self, kind: str) -> None:
        """Log the end of an outage, unless a later one extended it."""
        until = self._hold_until if kind == "hold" else self._refuse_until
        if self._now() >= until:
            log.warning("outage over: %s", "traffic flows again" if kind == "hold" else "connections accepted again")

    def stats(self) -> LinkStats:
        """Bytes, stalls and outages so far (a snapshot)."""
        now = self._now()
        return LinkStats(
            uptime=now - self._started_at,
            holding_for=max(0.0, self._hold_until - now),
            refusing_for=max(0.0, self._refuse_until - now),
            holds=self._holds,
            resets=self._resets,
            refused=self._refused,
            connections=[ConnectionStats(**vars(connection)) for connection in self._connections],
        )

    # ---- connections -----------------------------------------------------------------------------

    def _now(self) -> float:
        return asyncio.get_running_loop().time()

    async def _end_all(self, reason: str) -> None:
        tasks = list(self._tasks.values())
        for task in tasks:
            task.cancel(reason)
        await asyncio.gather(*tasks, return_exceptions=True)

    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = writer.get_extra_info("peername")
        if self._now() < self._refuse_until:
            self._refused += 1
            log.info("refused %s: the link is down", peer)
            _send_reset(writer)
            return
        connection = ConnectionStats(next(self._ids), f"{peer[0]}:{peer[1]}", self._now() - self._started_at)
        self._connections.append(connection)
        task = asyncio.current_task()
        assert task is not None  # asyncio runs each accepted connection in a task of its own
        self._tasks[connection.id] = task
        log.info("connection %d from %s", connection.id, connection.peer)
        try:
            connection.ended_by = await self._relay(connection, reader, writer)
        except asyncio.CancelledError:
            connection.ended_by = "reset by outage" if self._now() < self._refuse_until else "link closed"
            _send_reset(writer)
        finally:
            connection.closed = self._now() - self._started_at
            del self._tasks[connection.id]
            log.info("connection %d ended: %s", connection.id, connection.ended_by)

    async def _relay(
        self, connection: ConnectionStats, client_reader: asyncio.StreamReader, client_writer: asyncio.StreamWriter
    ) -> str:
        """Carry one connection until both directions ended; return how it ended."""
        accepted = self._now()
        upstream: _Streams = asyncio.get_running_loop().create_future()
        try:
            async with asyncio.TaskGroup() as group:
                group.create_task(self._connect_target(upstream))
                uplink = _Pipe(self, connection, Direction.UP, not_before=accepted + self.config.round_trip)
                group.create_task(uplink.run(_given(client_reader), _writer_of(upstream)))
                downlink = _Pipe(self, connection, Direction.DOWN, not_before=accepted)
                group.create_task(downlink.run(_reader_of(upstream), _given(client_writer)))
            client_writer.close()
            upstream.result()[1].close()
            return "closed"
        except BaseExceptionGroup as group:
            if group.subgroup(_PeerReset) is not None:
                return "reset by a peer"
            errors, others = group.split(OSError)
            if errors is not None and others is None:
                return f"error: {_first_leaf(errors)}"
            raise
        finally:
            if upstream.done() and not upstream.cancelled() and upstream.exception() is None:
                target_writer = upstream.result()[1]
                if not target_writer.is_closing():
                    _send_reset(target_writer)
            if not client_writer.is_closing():
                _send_reset(client_writer)

    async def _connect_target(self, upstream: _Streams) -> None:
        """The SYN crosses the link (waiting out a hold), then the target accepts or refuses.

        A refusal reaches the pipes through ``upstream``, which both of them await.
        """
        await self.sendable()
        await asyncio.sleep(self.config.up.delay)
        try:
            upstream.set_result(await asyncio.open_connection(*self.target))
        except OSError as exc:
            await asyncio.sleep(self.config.down.delay)  # the refusal travels back
            reason = os.strerror(exc.errno) if exc.errno else str(exc)
            upstream.set_exception(TargetUnreachable(f"target {self.target[0]}:{self.target[1]}: {reason}"))

    async def sendable(self, not_before: float = 0.0) -> None:
        """Return once a sender may transmit: after ``not_before`` and outside any hold."""
        while (wait := max(not_before, self._hold_until) - self._now()) > 0:
            await asyncio.sleep(wait)

    def line(self, direction: Direction) -> _Line:
        """The line that ``direction``'s connections share."""
        return self._lines[direction]


def _first_leaf(group: BaseExceptionGroup[BaseException]) -> BaseException:
    """The first exception in a (possibly nested) group, for a one-line reason."""
    first = group.exceptions[0]
    return _first_leaf(first) if isinstance(first, BaseExceptionGroup) else first


async def _given(value: _T) -> _T:
    return value


async def _reader_of(upstream: _Streams) -> asyncio.StreamReader:
    return (await upstream)[0]


async def _writer_of(upstream: _Streams) -> asyncio.StreamWriter:
    return (await upstream)[1]


class _Pipe:
    """One direction of one connection: read, transmit over the line, deliver in order."""

    def __init__(
        self, link: LinkEmulator, connection: ConnectionStats, direction: Direction, *, not_before: float
    ) -> None:
        self.link = link
        self.connection = connection
        self.direction = direction
        self.settings = link.config.direction(direction)
        self.not_before = not_before
        self.arrivals: asyncio.Queue[_Arrival] = asyncio.Queue()
        self.in_flight = 0
        self.window_open = asyncio.Event()
        self.window_open.set()

    async def run(self, source: Awaitable[asyncio.StreamReader], destination: Awaitable[asyncio.StreamWriter]) -> None:
        """Transmit from ``source`` and deliver to ``destination`` until the sender's FIN is delivered."""
        async with asyncio.TaskGroup() as group:
            group.create_task(self._transmit(source))
            group.create_task(self._deliver(destination))

    async def _transmit(self, source: Awaitable[asyncio.StreamReader]) -> None:
        reader = await source
        loop = asyncio.get_running_loop()
        offset, last, mss = 0, 0.0, self.link.config.mss
        while True:
            try:
                chunk = await reader.read(_READ_SIZE)
            except ConnectionError:
                self.arrivals.put_nowait(_Arrival(max(last, loop.time() + self.settings.delay), None, reset=True))
                return
            if not chunk:
                await self.link.sendable(self.not_before)  # the FIN is a segment too
                self.arrivals.put_nowait(_Arrival(max(last, loop.time() + self.settings.delay), None))
                return
            # Cut at multiples of the MSS in the stream, so a bulk transfer is cut the same way
            # however the kernel batched it; a message written on its own is a segment of its own.
            cuts = [0, *range(mss - offset % mss, len(chunk), mss), len(chunk)]
            for start, end in itertools.pairwise(cuts):
                segment = chunk[start:end]
                await self._window(len(segment))
                await self.link.sendable(self.not_before)
                sent = self.link.line(self.direction).reserve(len(segment) + SEGMENT_OVERHEAD, loop.time())
                if sent > loop.time():
                    await asyncio.sleep(sent - loop.time())  # the sender cannot push more while the line is busy
                fate = self.link.model.fate(self.direction, self.connection.id, offset)
                if fate.losses:
                    self.connection.stalled(self.direction)
                last = max(last, sent + self.settings.delay + fate.jitter + fate.stall)
                self.in_flight += len(segment)
                self.arrivals.put_nowait(_Arrival(last, segment))
                offset += len(segment)

    async def _window(self, nbytes: int) -> None:
        """Wait until the receive window has room (TCP's limit on bytes in flight)."""
        while self.in_flight and self.in_flight + nbytes > self.link.config.window:
            self.window_open.clear()
            await self.window_open.wait()

    async def _deliver(self, destination: Awaitable[asyncio.StreamWriter]) -> None:
        writer = await destination
        loop = asyncio.get_running_loop()
        while True:
            arrival = await self.arrivals.get()
            if arrival.at > loop.time():
                await asyncio.sleep(arrival.at - loop.time())
            if arrival.reset:
                raise _PeerReset()
            if arrival.data is None:
                if writer.can_write_eof():
                    writer.write_eof()
                return
            writer.write(arrival.data)
            await writer.drain()
            self.connection.count(self.direction, len(arrival.data))
            self.in_flight -= len(arrival.data)
            self.window_open.set()
