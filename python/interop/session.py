"""A rosbridge conversation over the suite's WebSocket: send ops, await the answers that match.

Every received message is kept in arrival order; ``expect`` takes the first one not yet taken
that matches, so a case can wait for an answer while other traffic (topic messages, status
lines, requests of a client-served service) piles up beside it.
"""

from __future__ import annotations

import asyncio
import hashlib
import hmac
import json
import os
import ssl
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .wire import Message, Recorder, WebSocket, WireClosed

__all__ = ["ROSBRIDGE_OPS", "Conversation", "Credentials", "Matcher", "NotAnswered", "auth_message", "op_is"]

Matcher = Callable[[dict[str, Any]], bool]

#: The ops of the protocol (docs/interop.md); a server that refuses one of these as unknown does
#: not implement it.
ROSBRIDGE_OPS = frozenset(
    {
        "advertise", "unadvertise", "publish", "subscribe", "unsubscribe", "call_service", "service_response",
        "advertise_service", "unadvertise_service", "send_action_goal", "cancel_action_goal", "action_feedback",
        "action_result", "advertise_action", "unadvertise_action", "fragment", "set_level", "auth",
    }
)  # fmt: skip


class NotAnswered(Exception):
    """What a case waited for did not come within its time (carries what did come)."""


@dataclass(frozen=True)
class Credentials:
    """The server's shared secret, for the HMAC ``auth`` message (P-AUTH-2)."""

    secret: str


def auth_message(secret: str, *, client: str = "interop", dest: str = "server", lifetime: int = 300) -> dict[str, Any]:
    """A rosauth-style ``auth`` op: mac = HMAC-SHA256(secret, client+dest+rand+t+level+end), hex."""
    now = int(time.time())
    rand = os.urandom(8).hex()
    level, end = "user", now + lifetime
    text = f"{client}{dest}{rand}{now}{level}{end}"
    mac = hmac.new(secret.encode(), text.encode(), hashlib.sha256).hexdigest()
    return {
        "op": "auth",
        "mac": mac,
        "client": client,
        "dest": dest,
        "rand": rand,
        "t": now,
        "level": level,
        "end": end,
    }


def op_is(op: str, **fields: Any) -> Matcher:
    """A matcher: this ``op`` and these field values."""

    def match(message: dict[str, Any]) -> bool:
        return message.get("op") == op and all(message.get(k) == v for k, v in fields.items())

    return match


class Conversation:
    """One connection to the server as a case uses it."""

    def __init__(self, socket: WebSocket, *, latency: float = 0.0, outage: float = 0.0) -> None:
        self.socket = socket
        # Over a long link every wait grows: ``latency`` (a round trip) for anything on its way,
        # twice that and ``outage`` for an answer that must come (a held link delays it that long).
        self.latency = latency
        self.outage = outage
        self.received: list[dict[str, Any]] = []
        self.raw: list[str | bytes] = []  # the same messages as they came (a NaN token or null)
        self._taken: set[int] = set()
        self._arrived = asyncio.Event()
        self._pump = asyncio.ensure_future(self._collect())

    @classmethod
    async def open(
        cls,
        url: str,
        recorder: Recorder,
        label: str,
        *,
        ssl_context: ssl.SSLContext | None = None,
        credentials: Credentials | None = None,
        latency: float = 0.0,
        outage: float = 0.0,
    ) -> Conversation:
        """Connect, and authenticate first when the server has a secret."""
        socket = await WebSocket.connect(url, recorder, label, ssl_context=ssl_context)
        conversation = cls(socket, latency=latency, outage=outage)
        if credentials is not None:
            await conversation.send(auth_message(credentials.secret))
        return conversation

    @property
    def closed(self) -> WireClosed | None:
        return self.socket.closed

    async def _collect(self) -> None:
        while True:
            try:
                message = await self.socket.receive()
            except WireClosed:
                self._arrived.set()
                return
            self.raw.append(message.data)
            self.received.append(decode(message))
            self._arrived.set()

    async def send(self, message: dict[str, Any]) -> None:
        await self.socket.send_text(json.dumps(message))

    async def send_text(self, text: str) -> None:
        await self.socket.send_text(text)

    def _find(self, match: Matcher) -> dict[str, Any] | None:
        for index, message in enumerate(self.received):
            if index not in self._taken and match(message):
                self._taken.add(index)
                return message
        return None

    async def expect(self, match: Matcher, timeout: float, what: str) -> dict[str, Any]:
        """The first untaken message that matches; ``NotAnswered`` after ``timeout`` (plus the
        link's latency and outage), ``WireClosed`` if the server closed the connection first."""
        return await self._wait(match, timeout + 2 * self.latency + self.outage, what)

    async def _wait(self, match: Matcher, timeout: float, what: str) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while True:
            found = self._find(match)
            if found is not None:
                return found
            if self.socket.closed is not None:
                raise self.socket.closed
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise NotAnswered(f"no {what} within {timeout:g} s")
            self._arrived.clear()
            try:
                await asyncio.wait_for(self._arrived.wait(), remaining)
            except TimeoutError:
                continue

    async def maybe(self, match: Matcher, timeout: float) -> dict[str, Any] | None:
        """Like ``expect``, but None when nothing matches in time (the connection may have closed)."""
        try:
            return await self.expect(match, timeout, "")
        except (NotAnswered, WireClosed):
            return None

    def discard(self, match: Matcher) -> int:
        """Mark every message received so far that matches as taken (stale requests); how many."""
        stale = [i for i, m in enumerate(self.received) if i not in self._taken and match(m)]
        self._taken.update(stale)
        return len(stale)

    async def poll(self, match: Matcher, timeout: float) -> dict[str, Any] | None:
        """Like ``maybe`` within exactly ``timeout`` (plus the link's latency only): for loops that
        repeat a request, and for windows in which nothing should arrive."""
        try:
            return await self._wait(match, timeout + self.latency if timeout else 0.0, "")
        except (NotAnswered, WireClosed):
            return None

    async def request(self, message: dict[str, Any], match: Matcher, timeout: float, what: str) -> dict[str, Any]:
        await self.send(message)
        return await self.expect(match, timeout, what)

    async def still_serves(self, timeout: float) -> bool:
        """Whether the connection still answers: a ``set_level`` is not answered, so this asks for
        a service that does not exist and waits for any answer to that call (P-SRV-5)."""
        probe = f"alive-{os.urandom(3).hex()}"
        try:
            await self.request(
                {"op": "call_service", "id": probe, "service": "/interop_probe/none", "timeout": 1.0},
                lambda m: m.get("id") == probe,
                timeout,
                "answer to a probe call",
            )
        except (NotAnswered, WireClosed):
            return False
        return True

    async def close(self) -> None:
        self._pump.cancel()
        await self.socket.close()


def decode(message: Message) -> dict[str, Any]:
    """A received message as a dict: JSON text parsed, binary frames under ``"binary"``, anything
    else under ``"unparsed"`` (a case decides what that means)."""
    if isinstance(message.data, bytes):
        return {"binary": message.data}
    try:
        value = json.loads(message.data)
    except ValueError:
        return {"unparsed": message.data}
    return value if isinstance(value, dict) else {"unparsed": message.data}
