"""The ground web server's own rosbridge connection for the 3D view: read-only, bounded, reconnecting.

Why a Python client here and not the Java connection of the run's PAX host: the web server is
asyncio and only reads (latched topics, throttled topics, read-only services); the PAX host's
connection lives in a JVM behind JPype, whose threads would have to call back into the event
loop for every frame, and its API is shaped for commands and typed telemetry. Commands still go
only through PAX (``Executive.operator_command``); this link never sends one. It uses the
binding's own rosbridge address and ``security`` (CA file, HMAC secret or token, as the Java
client does) and its ``link`` delay for timeouts, so it crosses the same link with the same trust.

Every subscription asks the bridge for what it needs at a bounded rate (``throttle_rate``,
``queue_length: 1``); after a reconnect the subscriptions are made again.
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
from collections.abc import Callable, Coroutine, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import websockets
from websockets.asyncio.client import ClientConnection

from pride.binding import read_binding
from rosbridge_wire import signed_login

__all__ = ["LinkError", "RosbridgeLink", "Subscription", "ViewLink", "read_view_link"]

log = logging.getLogger(__name__)

AT_NAMESPACE_SUFFIX = "/affordance_template_server"
RECONNECT_S = (1.0, 2.0, 5.0, 10.0)
_HELLO = "view-hello"


class LinkError(RuntimeError):
    """The rosbridge link refused, failed or did not answer; ``what`` names the request."""

    def __init__(self, what: str, message: str) -> None:
        super().__init__(f"{what}: {message}")
        self.what = what


@dataclass(frozen=True)
class ViewLink:
    """What the view needs of a binding: where its robot's rosbridge is, with what trust, and
    the robot's namespace (the AT server's namespace less ``/affordance_template_server``)."""

    url: str
    namespace: str
    one_way_delay: float = 0.0
    ca_file: Path | None = None
    secret: str | None = None
    token: str | None = None

    def name(self, relative: str) -> str:
        """A robot-relative ROS name (``joint_states``) under the robot's namespace."""
        return f"{self.namespace.rstrip('/')}/{relative}"


def read_view_link(path: str | Path, *, rosbridge_url: str | None = None) -> ViewLink | None:
    """The binding's link for the view (read by :func:`pride.binding.read_binding`), or None when
    it serves no Affordance Template system (nothing to show in 3D). ``rosbridge_url`` replaces
    the binding's address, as for PAX."""
    binding = read_binding(path)
    at_system = next((s for s in binding.systems if s.namespace.endswith(AT_NAMESPACE_SUFFIX)), None)
    if at_system is None:
        return None
    security = binding.security
    return ViewLink(
        url=rosbridge_url or at_system.rosbridge,
        namespace=at_system.namespace[: -len(AT_NAMESPACE_SUFFIX)] or "/",
        one_way_delay=binding.link.one_way_delay,
        ca_file=security.ca_file,
        secret=_read_secret(security.secret_file),
        token=_read_secret(security.token_file),
    )


def _read_secret(path: Path | None) -> str | None:
    return path.read_text(encoding="utf-8").strip() if path is not None else None


@dataclass
class Subscription:
    """One topic the view reads, with the rate it asks for."""

    topic: str
    type: str
    on_message: Callable[[Mapping[str, Any]], None]
    throttle_ms: int = 0
    queue_length: int = 1
    sub_id: str = field(default_factory=lambda: f"view-{secrets.token_hex(4)}")


class RosbridgeLink:
    """One rosbridge v2 connection kept open (reconnecting) until :meth:`close`.

    ``on_connected`` runs after every (re)connect, once the subscriptions are made again (the
    view then asks its services afresh: whatever it missed meanwhile is in their answers).
    """

    def __init__(
        self,
        link: ViewLink,
        *,
        on_connected: Callable[[], Coroutine[Any, Any, None]] | None = None,
        on_state: Callable[[str], None] | None = None,
    ) -> None:
        self.link = link
        self._subscriptions: list[Subscription] = []
        self._calls: dict[str, asyncio.Future[Any]] = {}
        self._ids = itertools.count(1)
        self._socket: ClientConnection | None = None
        self._on_connected = on_connected
        self._on_state = on_state or (lambda state: None)
        self._task: asyncio.Task[None] | None = None
        self._closed = False

    def subscribe(self, subscription: Subscription) -> None:
        """Read a topic from now on (and after every reconnect)."""
        self._subscriptions.append(subscription)
        if self._socket is not None:
            asyncio.get_running_loop().create_task(self._send(self._subscribe_message(subscription)))

    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._run())

    async def close(self) -> None:
        self._closed = True
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
        self._fail_calls("the view's link closed")

    @property
    def connected(self) -> bool:
        return self._socket is not None

    def call_timeout(self, base: float = 10.0) -> float:
        """A read-only call's timeout: ``base`` plus the round trip of the link."""
        return base + 2 * self.link.one_way_delay

    async def call(self, service: str, args: Mapping[str, Any], *, timeout: float | None = None) -> Mapping[str, Any]:
        """Call a read-only service; its ``values``. LinkError when refused, failed or unanswered."""
        if self._socket is None:
            raise LinkError(service, "not connected to rosbridge")
        call_id = f"view-call-{next(self._ids)}"
        future: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        self._calls[call_id] = future
        try:
            await self._send({"op": "call_service", "id": call_id, "service": service, "args": dict(args)})
            answer = await asyncio.wait_for(future, timeout if timeout is not None else self.call_timeout())
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
            "op": "subscribe",
            "id": s.sub_id,
            "topic": s.topic,
            "type": s.type,
            "throttle_rate": s.throttle_ms,
            "queue_length": s.queue_length,
        }

    def _auth_message(self) -> dict[str, Any] | None:
        if self.link.token is not None:
            return {"op": "auth", "token": self.link.token}
        if self.link.secret is None:
            return None
        return signed_login(self.link.secret, "pride-web-view", self.link.url, time.time())

    def _ssl(self) -> ssl.SSLContext | None:
        if not self.link.url.startswith("wss://"):
            return None
        return ssl.create_default_context(cafile=str(self.link.ca_file) if self.link.ca_file else None)

    async def _send(self, message: Mapping[str, Any]) -> None:
        socket = self._socket
        if socket is None:
            raise LinkError(str(message.get("op")), "not connected to rosbridge")
        await socket.send(json.dumps(message))

    def _fail_calls(self, why: str) -> None:
        for future in self._calls.values():
            if not future.done():
                future.set_result({"result": False, "values": why})

    async def _run(self) -> None:
        attempt = 0
        keepalive = max(5.0, 4 * self.link.one_way_delay)
        while not self._closed:
            try:
                async with websockets.connect(
                    self.link.url,
                    ssl=self._ssl(),
                    ping_interval=keepalive,
                    ping_timeout=keepalive + 2 * self.link.one_way_delay + 10,
                    open_timeout=10 + 2 * self.link.one_way_delay,
                    max_size=64 * 1024 * 1024,
                ) as socket:
                    auth = self._auth_message()
                    if auth is not None:
                        await socket.send(json.dumps(auth))
                    self._socket = socket
                    for subscription in self._subscriptions:
                        await self._send(self._subscribe_message(subscription))
                    # connected once the bridge answers (with auth, a refusal closes the socket instead)
                    await self._send(
                        {"op": "call_service", "id": _HELLO, "service": "/rosapi/get_ros_version", "args": {}}
                    )
                    async for frame in socket:
                        if self._receive(frame):
                            attempt = 0
                            self._on_state("connected")
                            if self._on_connected is not None:
                                asyncio.get_running_loop().create_task(self._on_connected())
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # refused, reset, TLS or auth failure: say so and try again
                log.warning("view link to %s: %s", self.link.url, exc)
            finally:
                self._socket = None
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
            log.warning("view link: a frame that is not JSON was dropped")
            return False
        if not isinstance(message, dict):
            return False
        op = message.get("op")
        if op == "service_response" and message.get("id") == _HELLO:
            return True
        if op == "publish":
            for subscription in self._subscriptions:
                if subscription.topic == message.get("topic") and isinstance(message.get("msg"), dict):
                    try:
                        subscription.on_message(message["msg"])
                    except Exception:  # a malformed message is reported, and the view keeps what it had
                        log.exception("view link: cannot use a message on %s", subscription.topic)
        elif op == "service_response":
            future = self._calls.get(str(message.get("id")))
            if future is not None and not future.done():
                future.set_result(message)
        elif op == "status" and message.get("level") in ("error", "warning"):
            log.warning("view link: rosbridge says %s", message.get("msg"))
        return False
