"""Calling one named ROS service for the ledger, and saying exactly what became of the call.

The outcome distinguishes what the ledger must never confuse: a call that was never made
(REFUSED: bad JSON, unknown type, no such service or no server) from one that was made but
not answered (UNKNOWN: it may have executed) and one that was answered (SUCCEEDED or FAILED).

The request is converted with the rosbridge server's conversion (:func:`request_message`, the
one place that calls it), so a ``request_json`` means the same to the ledger as to rosbridge.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from builtin_interfaces.msg import Time
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import InvalidServiceNameException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.validate_full_topic_name import validate_full_topic_name

from bridge.rosbridge.conversion import dict_to_message, load_type, message_to_dict, type_name
from bridge.rosbridge.protocol import BridgeError
from ros_process.command_order import stamp

from .store import State

__all__ = ["CallOutcome", "Refusal", "ServiceCaller", "request_message"]

SERVICE_QOS = QoSProfile(depth=1000, durability=DurabilityPolicy.VOLATILE, reliability=ReliabilityPolicy.RELIABLE)
"""Deep request/response queues like the robot side's services: ROS's default depth 10 drops
requests silently when more arrive together."""
DISCOVERY_WAIT_S = 10.0
"""How long a call waits for a service the graph does not list yet. A ledger or robot part that
has just (re)started is usually discovered over DDS within a second or two, but on a loaded
habitat computer it has taken more than 3 s; refusing then would fail a command that was only
early. The bridge gives a service call the same 10 s."""
SERVER_WAIT_S = 5.0
"""How long a call waits for a listed service's server to match the ledger's client."""
POLL_S = 0.05
"""Graph polling period: rclpy offers no graph-change event to wait on."""
SERVER_WATCH_S = 0.25
"""How often a pending call checks that its server is still there, so a server that dies
mid-call makes the outcome UNKNOWN at once rather than at the (possibly minutes-long) timeout."""


@dataclass(frozen=True)
class CallOutcome:
    """What became of one call. ``late_answer`` is set when an answer may still come."""

    state: State
    response_json: str
    message: str
    late_answer: Any = None  # an rclpy Future (rclpy is not annotated)


class Refusal(Exception):
    """The call cannot be made; ``str(refusal)`` says why and what to fix."""


def request_message(srv_cls: Any, request_json: str) -> Any:
    """The request of ``srv_cls`` filled from ``request_json``, by the rosbridge conversion.

    Raises:
        Refusal: not a JSON object, or a field does not fit the type.
    """
    try:
        data = json.loads(request_json) if request_json.strip() else {}
    except ValueError as exc:
        raise Refusal(f"request_json is not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise Refusal(f"request_json must be a JSON object, got {type(data).__name__}")
    try:
        return dict_to_message(srv_cls.Request, data, "request")
    except BridgeError as exc:
        raise Refusal(f"request_json does not fit {type_name(srv_cls)}: {exc}") from None


class ServiceCaller:
    """Cached clients of the services the ledger calls, on ``node``; thread-safe.

    Calls block their thread while they wait; the node's executor must run the clients' callback
    group on other threads (a MultiThreadedExecutor), so answers are taken meanwhile.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._group = ReentrantCallbackGroup()
        self._clients: dict[tuple[str, str], Any] = {}
        self._clients_lock = threading.Lock()

    def call(self, service: str, type_text: str, request_json: str, timeout: float, *, issued: float) -> CallOutcome:
        """Call ``service`` once and wait at most ``timeout`` s for its answer; a request with an
        ``issued`` field says the command was issued at ``issued`` (the robot side's clock)."""
        try:
            client, srv_cls = self._client(service, type_text)
            request = request_message(srv_cls, request_json)
        except Refusal as exc:
            return CallOutcome(State.REFUSED, "", str(exc))
        if isinstance(getattr(request, "issued", None), Time):
            request.issued = stamp(issued)  # the robot side's, whatever the client wrote there
        future = client.call_async(request)
        answered = threading.Event()
        future.add_done_callback(lambda _: answered.set())
        deadline = time.monotonic() + timeout
        while not answered.wait(min(SERVER_WATCH_S, max(0.0, deadline - time.monotonic()))):
            if time.monotonic() >= deadline:
                return CallOutcome(
                    State.UNKNOWN,
                    "",
                    f"no answer from {service} within {timeout:g} s; it may have"
                    " executed (an answer that comes later is recorded)",
                    late_answer=future,
                )
            if not client.service_is_ready():
                client.remove_pending_request(future)
                return CallOutcome(
                    State.UNKNOWN, "", f"the server of {service} went away before answering; it may have executed"
                )
        return answer_outcome(service, future)

    def _client(self, service: str, type_text: str) -> tuple[Any, Any]:
        try:
            validate_full_topic_name(service, is_service=True)
        except InvalidServiceNameException as exc:
            raise Refusal(" ".join(str(exc).split())) from None
        graph_type = self._graph_type(service, wait=DISCOVERY_WAIT_S)
        if type_text:
            try:
                srv_cls = load_type(type_text, "srv")
            except BridgeError as exc:
                raise Refusal(str(exc)) from None
            if graph_type is not None and graph_type != type_name(srv_cls):
                raise Refusal(f"service {service} has type {graph_type}, not {type_name(srv_cls)}")
        elif graph_type is None:
            raise Refusal(f"service {service} does not exist (nothing on the ROS graph offers it)")
        else:
            try:
                srv_cls = load_type(graph_type, "srv")
            except BridgeError as exc:
                raise Refusal(f"service {service}: {exc}") from None
        with self._clients_lock:
            client = self._clients.get((service, type_name(srv_cls)))
            if client is None:
                client = self._node.create_client(srv_cls, service, qos_profile=SERVICE_QOS, callback_group=self._group)
                self._clients[(service, type_name(srv_cls))] = client
        if not _wait_until(client.service_is_ready, SERVER_WAIT_S):
            raise Refusal(f"service {service} has no server answering")
        return client, srv_cls

    def _graph_type(self, service: str, *, wait: float) -> str | None:
        found: list[str] = []

        def listed() -> bool:
            found[:] = [
                types[0] for name, types in self._node.get_service_names_and_types() if name == service and types
            ]
            return bool(found)

        return found[0] if _wait_until(listed, wait) else None


def answer_outcome(service: str, future: Any) -> CallOutcome:
    """The outcome of a call whose rclpy future is done: the service's answer, or UNKNOWN."""
    if future.cancelled() or future.exception() is not None:
        return CallOutcome(
            State.UNKNOWN,
            "",
            f"the call of {service} ended without an answer"
            f" ({future.exception() or 'cancelled'}); it may have executed",
        )
    response = message_to_dict(future.result())
    text = json.dumps(response, allow_nan=False, separators=(",", ":"))
    message = response.get("message")
    reported = message if isinstance(message, str) else ""
    if response.get("success") is False:
        return CallOutcome(State.FAILED, text, reported or f"{service} answered success false")
    return CallOutcome(State.SUCCEEDED, text, reported)


def _wait_until(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() >= deadline:
            return False
        threading.Event().wait(POLL_S)  # the graph has no event to wait on (see POLL_S)
    return True


def valid_timeout(value: float, default: float, limit: float) -> float:
    """``value`` s if it is a usable timeout, ``default`` for 0.

    Raises:
        Refusal: negative, not finite, or above ``limit``.
    """
    if value == 0.0:
        return default
    if not math.isfinite(value) or value < 0 or value > limit:
        raise Refusal(f"timeout must be 0 (the ledger's default) or a number of seconds up to {limit:g}, got {value}")
    return value
