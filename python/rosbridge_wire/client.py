"""An asyncio rosbridge v2 client kept connected: subscriptions, service calls, advertised services.

Used where a Python part of the procedure side talks rosbridge by itself (not through PAX's Java
client): the console's 3D view link, and the onboard executive and its ground supervisor. It
crosses the link with the binding's trust (wss with a CA file, an HMAC login with the shared
secret or a bearer token) and its delay (timeouts and keepalives grow with the one-way delay).

After a reconnect the subscriptions and advertised services are made again and ``on_connected``
runs: whatever a caller missed meanwhile it asks for again (calls in flight are failed at once
with the reason, never left waiting for an answer that cannot come).
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import logging
import secrets
import ssl
import time
from collections.abc import Awaitable, Callable, Coroutine, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import websockets
from websockets.asyncio.client import ClientConnection

from rosbridge_wire import (
    OP_ADVERTISE_SERVICE,
    OP_CALL_SERVICE,
    OP_SERVICE_RESPONSE,
    OP_SUBSCRIBE,
    OP_UNSUBSCRIBE,
    signed_login,
)
from rosbridge_wire.light_time import LightTime

__all__ = ["Endpoint", "LinkError", "RosbridgeClient", "ServiceHandler", "Subscription"]

log = logging.getLogger(__name__)

RECONNECT_S = (1.0, 2.0, 5.0, 10.0)
_HELLO = "hello"

#: An advertised service's handler: the request's ``args`` → the response's ``values``. Raising
#: answers the call with ``result: false`` and the error's text.
ServiceHandler = Callable[[Mapping[str, Any]], Awaitable[Mapping[str, Any]]]


class LinkError(RuntimeError):
    """The rosbridge link refused, failed or did not answer; ``what`` names the request."""

    def __init__(self, what: str, message: str) -> None:
        super().__init__(f"{what}: {message}")
        self.what = what


@dataclass(frozen=True)
class Endpoint:
    """Where a bridge is and with what trust: its URL, the link's one-way delay, a CA file for
    wss, and the shared secret (HMAC login) or bearer token it wants."""

    url: str
    one_way_delay: float = 0.0
    ca_file: Path | None = None
    secret: str | None = None
    token: str | None = None

    @property
    def light_time(self) -> LightTime:
        """What the link's delay makes of every wait across it."""
        return LightTime(self.one_way_delay)


@dataclass
class Subscription:
    """One topic read, with the rate asked for."""

    topic: str
    type: str  # "": the bridge reads it from the ROS graph
    on_message: Callable[[Mapping[str, Any]], None]
    throttle_ms: int = 0
    queue_length: int = 1
    sub_id: str = field(default_factory=lambda: f"sub-{secrets.token_hex(4)}")


@dataclass(frozen=True)
class _Advertised:
    service: str
    type: str
    handler: ServiceHandler


class RosbridgeClient:
    """One rosbridge v2 connection kept open (reconnecting) until :meth:`close`.

    ``name`` is the client's name in its login (the bridge's log shows it).
    """

    def __init__(
        self,
        endpoint: Endpoint,
        *,
        name: str,
        on_connected: Callable[[], Coroutine[Any, Any, None]] | None = None,
        on_state: Callable[[str], None] | None = None,
    ) -> None:
        self.endpoint = endpoint
        self.name = name
        self._subscriptions: list[Subscription] = []
        self._advertised: list[_Advertised] = []
        self._calls: dict[str, asyncio.Future[Any]] = {}
        self._ids = itertools.count(1)
        self._socket: ClientConnection | None = None
        self._on_connected = on_connected
        self._on_state = on_state or (lambda state: None)
        self._task: asyncio.Task[None] | None = None
        self._handling: set[asyncio.Task[None]] = set()
        self._closed = False
        self.ready = asyncio.Event()
        """Set while connected (the bridge answered the greeting)."""
        self.opened = asyncio.Event()
        """Set while the socket is open and the login and the greeting have gone out on it.

        A request sent from then on goes right behind them: the bridge takes frames in order, so it
        is answered after the login is (or lost with the socket when the login is refused). Across
        a long link that saves the round trip of waiting for :attr:`ready`, for a caller that may
        send the same request again (an uplinked unit, a request for events)."""

    def subscribe(self, subscription: Subscription) -> None:
        """Read a topic from now on (and after every reconnect)."""
        self._subscriptions.append(subscription)
        if self._socket is not None:
            asyncio.get_running_loop().create_task(self._send_or_redo(self._subscribe_message(subscription)))

    async def unsubscribe(self, subscription: Subscription) -> None:
        """Stop reading ``subscription``'s topic (and do not read it again after a reconnect)."""
        if subscription in self._subscriptions:
            self._subscriptions.remove(subscription)
            unsubscribe = {"op": OP_UNSUBSCRIBE, "id": subscription.sub_id, "topic": subscription.topic}
            await self._send_or_redo(unsubscribe)  # a lost connection has forgotten it already

    def advertise_service(self, service: str, type_: str, handler: ServiceHandler) -> None:
        """Serve ``service`` (of ROS type ``type_``) through the bridge from now on (and after every reconnect)."""
        advertised = _Advertised(service, type_, handler)
        self._advertised.append(advertised)
        if self._socket is not None:
            asyncio.get_running_loop().create_task(self._send_or_redo(self._advertise_message(advertised)))

    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._run())

    async def close(self) -> None:
        self._closed = True
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
        for task in list(self._handling):
            task.cancel()
        self._fail_calls(f"{self.name}'s link closed")

    @property
    def connected(self) -> bool:
        return self._socket is not None

    def call_timeout(self, base: float = 10.0) -> float:
        """A call's timeout: ``base`` plus the round trip of the link."""
        return self.endpoint.light_time.answer_within(base)

    async def call(self, service: str, args: Mapping[str, Any], *, timeout: float | None = None) -> Mapping[str, Any]:
        """Call a service; its ``values``. LinkError when refused, failed or unanswered."""
        if self._socket is None:
            raise LinkError(service, "not connected to rosbridge")
        call_id = f"{self.name}-call-{next(self._ids)}"
        wait = timeout if timeout is not None else self.call_timeout()
        future: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        self._calls[call_id] = future
        try:
            # the bridge waits for the service as long as the caller does, less the way back
            request = {
                "op": OP_CALL_SERVICE,
                "id": call_id,
                "service": service,
                "args": dict(args),
                "timeout": max(1.0, wait - self.endpoint.light_time.round_trip),
            }
            await self._send(request)
            answer = await asyncio.wait_for(future, wait)
        except TimeoutError:
            raise LinkError(service, "no answer in time") from None
        finally:
            self._calls.pop(call_id, None)
        if (
            not isinstance(answer, dict)
            or answer.get("result") is not True
            or not isinstance(answer.get("values"), dict)
        ):
            raise LinkError(service, str(answer.get("values") if isinstance(answer, dict) else answer))
        values: Mapping[str, Any] = answer["values"]
        return values

    # ---- the connection ---------------------------------------------------------------------
    def _subscribe_message(self, s: Subscription) -> dict[str, Any]:
        return {
            "op": OP_SUBSCRIBE,
            "id": s.sub_id,
            "topic": s.topic,
            **({"type": s.type} if s.type else {}),  # none: the bridge reads it from the graph
            "throttle_rate": s.throttle_ms,
            "queue_length": s.queue_length,
        }

    @staticmethod
    def _advertise_message(a: _Advertised) -> dict[str, Any]:
        return {"op": OP_ADVERTISE_SERVICE, "service": a.service, "type": a.type}

    def _auth_message(self) -> dict[str, Any] | None:
        if self.endpoint.token is not None:
            return {"op": "auth", "token": self.endpoint.token}
        if self.endpoint.secret is None:
            return None
        lifetime = self.endpoint.light_time.login_lifetime  # it must arrive valid
        return signed_login(self.endpoint.secret, self.name, self.endpoint.url, time.time(), lifetime=lifetime)

    def _ssl(self) -> ssl.SSLContext | None:
        if not self.endpoint.url.startswith("wss://"):
            return None
        return ssl.create_default_context(cafile=str(self.endpoint.ca_file) if self.endpoint.ca_file else None)

    async def _send(self, message: Mapping[str, Any]) -> None:
        socket = self._socket
        if socket is None:
            raise LinkError(str(message.get("op")), "not connected to rosbridge")
        try:
            await socket.send(json.dumps(message))
        except (websockets.ConnectionClosed, OSError) as exc:  # lost while sending: the caller asks again
            raise LinkError(str(message.get("op")), f"the connection was lost: {exc}") from None

    async def _send_or_redo(self, message: Mapping[str, Any]) -> None:
        """Send a subscription or advertisement now; one lost with the connection is made again on reconnect."""
        with contextlib.suppress(LinkError):
            await self._send(message)

    def _fail_calls(self, why: str) -> None:
        for future in self._calls.values():
            if not future.done():
                future.set_result({"result": False, "values": why})

    async def _run(self) -> None:
        attempt = 0
        light = self.endpoint.light_time
        while not self._closed:
            tls = self._ssl()
            # asyncio gives a TLS handshake 60 s of its own: too short past about 20 s one way
            handshake: dict[str, Any] = {"ssl_handshake_timeout": light.connect_within} if tls is not None else {}
            try:
                async with websockets.connect(
                    self.endpoint.url,
                    ssl=tls,
                    ping_interval=light.keepalive,
                    ping_timeout=light.keepalive_timeout,
                    open_timeout=light.connect_within,
                    max_size=64 * 1024 * 1024,
                    **handshake,
                ) as socket:
                    auth = self._auth_message()
                    if auth is not None:
                        await socket.send(json.dumps(auth))
                    self._socket = socket
                    for subscription in self._subscriptions:
                        await self._send(self._subscribe_message(subscription))
                    for advertised in self._advertised:
                        await self._send(self._advertise_message(advertised))
                    # connected once the bridge answers (with auth, a refusal closes the socket instead)
                    await self._send(
                        {"op": OP_CALL_SERVICE, "id": _HELLO, "service": "/rosapi/get_ros_version", "args": {}}
                    )
                    self.opened.set()
                    async for frame in socket:
                        if self._receive(frame):
                            attempt = 0
                            self.ready.set()
                            self._on_state("connected")
                            if self._on_connected is not None:
                                asyncio.get_running_loop().create_task(self._on_connected())
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # refused, reset, TLS or auth failure: say so and try again
                log.warning("%s: rosbridge link to %s: %s", self.name, self.endpoint.url, exc)
            finally:
                self._socket = None
                self.opened.clear()
                self.ready.clear()
                self._fail_calls("the rosbridge connection was lost")
            if self._closed:
                return
            self._on_state("reconnecting")
            await asyncio.sleep(RECONNECT_S[min(attempt, len(RECONNECT_S) - 1)])
            attempt += 1

    def _receive(self, frame: str | bytes) -> bool:
        """Deliver one frame; True when it is the bridge's answer to the greeting."""
        try:
            message = json.loads(frame)
        except ValueError:
            log.warning("%s: a frame that is not JSON was dropped", self.name)
            return False
        if not isinstance(message, dict):
            return False
        op = message.get("op")
        if op == OP_SERVICE_RESPONSE and message.get("id") == _HELLO:
            return True
        if op == "publish":
            for subscription in self._subscriptions:
                if subscription.topic == message.get("topic") and isinstance(message.get("msg"), dict):
                    try:
                        subscription.on_message(message["msg"])
                    except Exception:  # a malformed message is reported, and the reader keeps what it had
                        log.exception("%s: cannot use a message on %s", self.name, subscription.topic)
        elif op == OP_SERVICE_RESPONSE:
            future = self._calls.get(str(message.get("id")))
            if future is not None and not future.done():
                future.set_result(message)
        elif op == OP_CALL_SERVICE:
            advertised = next((a for a in self._advertised if a.service == message.get("service")), None)
            if advertised is not None:
                task = asyncio.get_running_loop().create_task(self._serve(advertised, message))
                self._handling.add(task)
                task.add_done_callback(self._handling.discard)
        elif op == "status" and message.get("level") in ("error", "warning"):
            log.warning("%s: rosbridge says %s", self.name, message.get("msg"))
        return False

    async def _serve(self, advertised: _Advertised, request: Mapping[str, Any]) -> None:
        """Answer one call of an advertised service; a failing handler answers ``result: false``."""
        args = request.get("args")
        answer: dict[str, Any] = {"op": OP_SERVICE_RESPONSE, "service": advertised.service, "id": request.get("id")}
        try:
            if not isinstance(args, dict):
                raise ValueError(f"the request's args must be an object, not {type(args).__name__}")
            answer.update(result=True, values=dict(await advertised.handler(args)))
        except Exception as exc:  # said to the caller; the service stays up for the next call
            log.exception("%s: %s failed", self.name, advertised.service)
            answer.update(result=False, values=f"{type(exc).__name__}: {exc}")
        with contextlib.suppress(LinkError):  # the caller asks again after a reconnect
            await self._send(answer)
