"""Services both ways: clients calling ROS services, and clients serving ROS services.

Calls use one cached rclpy client per (service, type): creating a client per call costs about
85 ms of discovery, which was the whole service tail of the peers.  A call never blocks the
event loop or other calls: the rclpy future's completion is handed back through
:meth:`RosThread.deliver` and awaited with a per-call (or the default) timeout.

A client-served service is a ROS service on ``RosThread.server_node`` whose coroutine callback
forwards each request as ``call_service`` (id ``service_request:<service>:<n>``) and awaits
the client's ``service_response``.  A ROS service cannot report failure, so a request the
client fails (``result: false``, bad values, disconnect, unadvertise) gets no response and the
caller's own timeout reports it; the failure is logged, never turned into a fake success.

Parameters are guarded whichever way a client reaches them: a call of any node's
``set_parameters``/``set_parameters_atomically`` (directly, or through rosapi's ``set_param``)
is refused unless every parameter is allowed by ``--set-params-glob``, and ``get_parameters``
reads only what ``--params-glob`` allows.  At most :data:`MAX_CLIENTS` service clients are
kept; the least recently used one without a call in flight goes first.
"""

from __future__ import annotations

import asyncio
import fnmatch
import itertools
import json
import logging
import time
from dataclasses import dataclass, field
from typing import Any

import rclpy.task
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.qos import QoSProfile, ReliabilityPolicy

from .conversion import dict_to_message, list_to_request, load_type, message_to_dict, type_name
from .limits import Quotas
from .protocol import (
    MAX_TEXT,
    OP_CALL_SERVICE,
    SERVICE_TIMEOUT_TEXT,
    InvalidField,
    ServiceTimeout,
    ServiceUnanswered,
    ServiceUnavailable,
    TypeConflict,
    client_text,
    echo,
)
from .ros_thread import RosThread
from .security import Policy
from .session import Session

log = logging.getLogger(__name__)

CLIENT_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
"""Deep request/response history: with the default depth 10, a burst of concurrent calls
overwrites requests not yet acknowledged and responses not yet taken, and those calls hang."""
SERVER_WAIT_S = 1.0
"""How long a call waits for a known service's server to match (rosbridge: 1 s)."""
DISCOVERY_WAIT_S = 3.0
"""How long a call waits for a service the graph does not list yet: a bridge that has just
(re)started discovers the robot's services over DDS within a second or two, and a client that
reconnected to it must not be told they do not exist."""
SERVER_WATCH_S = 0.25
"""How often a pending call checks that its server is still there: a server that dies
mid-call fails the call at once instead of at its (possibly minutes-long) timeout."""
MAX_CLIENTS = 256
GRAPH_AGE_S = 0.05
READY_CHECK_S = 0.5
"""How often the graph is looked at for new services to keep a client ready for (``--ready-services``)."""
_PARAMETER_WRITES = {"rcl_interfaces/srv/SetParameters", "rcl_interfaces/srv/SetParametersAtomically"}
_PARAMETER_READS = {"rcl_interfaces/srv/GetParameters"}


@dataclass
class ProvidedService:
    """A ROS service whose requests a WebSocket client answers."""

    name: str
    srv_cls: Any
    session: Session
    service: Any = None
    pending: dict[str, rclpy.task.Future] = field(default_factory=dict)
    counter: itertools.count[int] = field(default_factory=lambda: itertools.count(1))


class Services:
    """Service calls from clients, and services provided by clients."""

    def __init__(
        self, ros: RosThread, default_timeout: float, quotas: Quotas, policy: Policy, ready: tuple[str, ...] = ()
    ) -> None:
        """``ready``: globs of services whose client is made as soon as the graph shows them
        (:meth:`keep_ready`)."""
        self.ros = ros
        self.ready = ready
        self.default_timeout = default_timeout
        self.quotas = quotas
        self.policy = policy
        self._clients: dict[str, tuple[Any, Any]] = {}  # least recently used first
        self._in_flight: dict[str, int] = {}
        self._graph: tuple[float, dict[str, str]] = (-1.0, {})
        self._matched: set[str] = set()  # services whose server matched their cached client
        self.provided: dict[str, ProvidedService] = {}

    # --- calling ROS services ----------------------------------------------------------------
    def graph_type(self, service: str) -> str | None:
        """The type of ``service`` on the ROS graph, or None if no server offers it."""
        return self.graph().get(service)

    def graph(self) -> dict[str, str]:
        """Service name -> type on the ROS graph, read at most every :data:`GRAPH_AGE_S`: calls
        waiting for a service to appear all poll it, and a graph query costs a millisecond."""
        now = time.monotonic()
        if now - self._graph[0] > GRAPH_AGE_S:
            names = {name: types[0] for name, types in self.ros.node.get_service_names_and_types() if types}
            self._graph = (now, names)
        return self._graph[1]

    async def _discovered_client(self, service: str, timeout: float) -> tuple[Any, Any]:
        """The cached client of ``service``, waiting up to ``timeout`` for DDS to discover it."""
        deadline = asyncio.get_running_loop().time() + timeout
        while service not in self._clients and self.graph_type(service) is None:
            if asyncio.get_running_loop().time() > deadline:
                break
            await asyncio.sleep(0.05)  # rclpy offers no graph-change event to await here
        return self._client(service)

    def _client(self, service: str) -> tuple[Any, Any]:
        cached = self._clients.pop(service, None)
        if cached is not None:
            self._clients[service] = cached  # now the most recently used
            return cached
        graph_type = self.graph_type(service)
        if graph_type is None:
            raise ServiceUnavailable(f"Service {service} does not exist")
        srv_cls = load_type(graph_type, "srv")
        idle = [name for name in self._clients if not self._in_flight.get(name)]
        for name in idle[: max(0, len(self._clients) + 1 - MAX_CLIENTS)]:
            self._forget_client(name)
        client = self.ros.node.create_client(srv_cls, service, qos_profile=CLIENT_QOS)
        cached = self._clients[service] = (client, srv_cls)
        return cached

    async def keep_ready(self) -> None:
        """Make the client of every service matching :attr:`ready` as soon as the graph shows it,
        and again after it was dropped (its server died).

        The first call through a new client waits for DDS to match it with the server: about
        0.1 s quiet, more on a busy machine. For a halt that delay is the arm moving on, so its
        clients are matched before anybody needs them. (rclpy has no graph event: the graph is
        looked at every :data:`READY_CHECK_S`.)
        """
        unready: set[str] = set()  # said once each: their type does not load (a call will say so too)
        while self.ready:
            for service in self.graph():
                if (
                    service in self._clients
                    or service in unready
                    or not any(fnmatch.fnmatchcase(service, glob) for glob in self.ready)
                ):
                    continue
                try:
                    self._client(service)
                except Exception as exc:
                    unready.add(service)
                    log.warning("cannot keep a client ready for %s: %s", service, exc)
            await asyncio.sleep(READY_CHECK_S)

    def _check_parameters(self, service: str, srv_cls: Any, request: Any) -> None:
        """Refuse parameter reads and writes the allow-lists do not allow (see module doc)."""
        kind = type_name(srv_cls)
        if kind in _PARAMETER_WRITES:
            node = service.rsplit("/", 1)[0]
            for parameter in request.parameters:
                self.policy.set_params.check(f"{node}:{parameter.name}")
        elif kind in _PARAMETER_READS:
            node = service.rsplit("/", 1)[0]
            for name in request.names:
                self.policy.params.check(f"{node}:{name}")

    def _forget_client(self, service: str) -> None:
        # After a failure the server may be gone or replaced with another type: look again next time.
        self._matched.discard(service)
        cached = self._clients.pop(service, None)
        if cached is not None:
            self.ros.node.destroy_client(cached[0])

    def request_class(self, service: str) -> Any:
        """The request class of a service on the graph (for rosapi details)."""
        return self._client(service)[1]

    async def call(self, service: str, args: Any, timeout: float | None) -> dict[str, Any]:
        """Call a ROS service; the response as a dict.  Raises a BridgeError on failure."""
        limit = timeout if timeout and timeout > 0 else self.default_timeout
        client, srv_cls = await self._discovered_client(service, min(limit, DISCOVERY_WAIT_S))
        if isinstance(args, list):
            request = list_to_request(srv_cls.Request, args)
        else:
            request = dict_to_message(srv_cls.Request, args or {}, "args")
        self._check_parameters(service, srv_cls, request)
        self._in_flight[service] = self._in_flight.get(service, 0) + 1
        try:
            return await self._call(service, client, request, limit)
        finally:
            left = self._in_flight.pop(service) - 1
            if left:
                self._in_flight[service] = left

    async def _call(self, service: str, client: Any, request: Any, limit: float) -> dict[str, Any]:
        if service not in self._matched:
            if not await self._server_matched(client):
                self._forget_client(service)
                raise ServiceUnavailable(f"Service {service} has no server answering")
            self._matched.add(service)
        ros_future = client.call_async(request)
        answer = self.ros.wrap(ros_future)
        ended = ""  # why the bridge gave up on the answer: "timeout" or "server lost"

        def end(reason: str) -> None:
            nonlocal ended
            ended = reason
            answer.cancel()

        async def watch_server() -> None:
            while True:
                await asyncio.sleep(SERVER_WATCH_S)
                if not client.service_is_ready():
                    end("server lost")
                    return

        expiry = asyncio.get_running_loop().call_later(limit, end, "timeout")
        watcher = asyncio.get_running_loop().create_task(watch_server())
        try:
            response = await answer
        except asyncio.CancelledError:
            client.remove_pending_request(ros_future)
            if ended == "timeout":
                self._matched.discard(service)  # check again next time that its server is still there
                raise ServiceTimeout(SERVICE_TIMEOUT_TEXT) from None
            if ended == "server lost":
                self._forget_client(service)
                raise ServiceUnavailable(f"Service {service} lost its server before answering") from None
            raise
        finally:
            expiry.cancel()
            watcher.cancel()
        return message_to_dict(response)

    async def _server_matched(self, client: Any) -> bool:
        """Wait up to SERVER_WAIT_S for a server known on the graph to match the client."""
        deadline = asyncio.get_running_loop().time() + SERVER_WAIT_S
        while not client.service_is_ready():
            if asyncio.get_running_loop().time() > deadline:
                return False
            await asyncio.sleep(0.01)  # rclpy offers no readiness event to await
        return True

    # --- services served by clients ----------------------------------------------------------
    def advertise(self, session: Session, service: str, type_name_: str) -> None:
        srv_cls = load_type(type_name_, "srv")
        previous = self.provided.get(service)
        if previous is None and self.graph_type(service) not in (None, type_name(srv_cls)):
            raise TypeConflict(f"service {service} already exists with type {self.graph_type(service)}")
        self.quotas.advertisements.take(session.number)
        if previous is not None:  # rosbridge semantics: the newest advertiser replaces the old one
            self._withdraw(previous, "replaced by a newer advertise_service")
        provided = ProvidedService(service, srv_cls, session)

        async def callback(request: Any, response: Any) -> Any:
            return await self._forward_request(provided, request)

        try:
            # Reentrant: requests are forwarded side by side, so one its client is slow to answer
            # (a long poll, a client that never answers) does not hold the calls behind it.
            provided.service = self.ros.server_node.create_service(
                srv_cls, service, callback, callback_group=ReentrantCallbackGroup()
            )
        except Exception as exc:
            self.quotas.advertisements.give(session.number)
            raise InvalidField(f"cannot advertise service {service}: {type(exc).__name__}") from None
        self.provided[service] = provided

    def unadvertise(self, session: Session, service: str) -> None:
        provided = self.provided.get(service)
        if provided is None or provided.session is not session:
            raise InvalidField(f"service {service} is not advertised by this client")
        self._withdraw(provided, "unadvertised by its client")

    def respond(self, session: Session, service: str, request_id: str, values: Any, result: bool) -> None:
        """A client's ``service_response`` to a forwarded request."""
        provided = self.provided.get(service)
        future = provided.pending.pop(request_id, None) if provided and provided.session is session else None
        if provided is None or future is None:
            raise InvalidField(f"no pending request {echo(request_id)!r} for service {service} of this client")
        try:
            response = dict_to_message(provided.srv_cls.Response, values or {}, "values") if result else None
        except InvalidField as exc:
            future.set_exception(RuntimeError(str(exc)))
            raise
        finally:
            self.ros.server_executor.wake()
        if response is None:
            why = values if isinstance(values, str) else json.dumps(values)[:MAX_TEXT]  # the client's words, bounded
            future.set_exception(RuntimeError(f"the client serving {service} failed the request: {client_text(why)}"))
        else:
            future.set_result(response)
        self.ros.server_executor.wake()

    async def _forward_request(self, provided: ProvidedService, request: Any) -> Any:
        # Runs on the ros-servers thread, inside the executor's task machinery.
        request_id = f"service_request:{provided.name}:{next(provided.counter)}"
        future = rclpy.task.Future()
        provided.pending[request_id] = future
        message = {"op": OP_CALL_SERVICE, "id": request_id, "service": provided.name, "args": message_to_dict(request)}
        self.ros.deliver(provided.session.send, message)
        try:
            return await future
        except Exception:
            text = f"request {request_id} of {provided.name} not answered: {future.exception()}"
            self.ros.deliver(provided.session.log, logging.WARNING, text)
            raise ServiceUnanswered(text) from None

    def _withdraw(self, provided: ProvidedService, reason: str) -> None:
        if self.provided.get(provided.name) is provided:
            del self.provided[provided.name]
        self.quotas.advertisements.give(provided.session.number)
        for future in provided.pending.values():
            future.set_exception(RuntimeError(f"service {provided.name} {reason}"))
        provided.pending.clear()
        # On the executor's own thread, as for actions (actions.py): never under its wait.
        self.ros.on_server_thread(self.ros.server_node.destroy_service, provided.service)

    def drop_session(self, session: Session) -> None:
        """Withdraw the services a closed session provided."""
        for provided in [p for p in self.provided.values() if p.session is session]:
            self._withdraw(provided, "lost its client")
