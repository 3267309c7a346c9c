"""The op dispatch of rosbridge v2 and the one boundary where failures become answers.

:meth:`Bridge.handle` parses a frame, checks fields and allow-lists, and runs the op's
handler.  Any :class:`BridgeError` (or unexpected exception) raised on the way is answered in
the form the op's client waits for: ``service_response`` with ``result: false`` and the reason
as ``values`` for ``call_service``, ``action_result`` with ``result: false`` for
``send_action_goal``, and for every op a ``status`` message (if the client asked for one
with ``set_level``) naming op, id and reason.  The connection stays up.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from . import protocol as p
from .protocol import BridgeError, InvalidField, MalformedMessage, UnknownOperation, optional, require
from .rosapi import Rosapi
from .security import AllowList
from .services import Services
from .session import Session
from .topics import Topics

log = logging.getLogger(__name__)

FRAGMENT_TIMEOUT_S = 600.0


@dataclass
class Policy:
    """Server-wide limits and allow-lists."""

    topics: AllowList = field(default_factory=lambda: AllowList("topic"))
    services: AllowList = field(default_factory=lambda: AllowList("service"))
    actions: AllowList = field(default_factory=lambda: AllowList("action"))
    max_message_size: int = 10_000_000


@dataclass
class PendingFragments:
    """Parts of one fragmented incoming message."""

    total: int
    started: float
    parts: dict[int, str] = field(default_factory=dict)
    size: int = 0


class Bridge:
    """Routes each client op to topics, services, actions or rosapi."""

    def __init__(self, topics: Topics, services: Services, actions: Any, policy: Policy) -> None:
        self.topics = topics
        self.services = services
        self.actions = actions
        self.rosapi = Rosapi(topics, services)
        self.policy = policy
        self._fragments: dict[int, dict[Any, PendingFragments]] = {}
        self._tasks: dict[int, set[asyncio.Task[Any]]] = {}
        self._ops: dict[str, Callable[[Session, dict[str, Any]], Any]] = {
            p.OP_ADVERTISE: self._advertise, p.OP_UNADVERTISE: self._unadvertise, p.OP_PUBLISH: self._publish,
            p.OP_SUBSCRIBE: self._subscribe, p.OP_UNSUBSCRIBE: self._unsubscribe,
            p.OP_CALL_SERVICE: self._call_service, p.OP_SERVICE_RESPONSE: self._service_response,
            p.OP_ADVERTISE_SERVICE: self._advertise_service, p.OP_UNADVERTISE_SERVICE: self._unadvertise_service,
            p.OP_FRAGMENT: self._fragment, p.OP_SET_LEVEL: self._set_level, p.OP_AUTH: self._auth_again,
        }
        if actions is not None:
            self._ops.update(actions.operations())

    # --- the boundary --------------------------------------------------------------------------
    def handle_frame(self, session: Session, frame: str | bytes) -> None:
        """Parse one incoming frame and handle it; every failure is answered."""
        message: Any = None
        try:
            if isinstance(frame, bytes):
                raise MalformedMessage("binary frames are not accepted: send JSON text frames")
            try:
                message = json.loads(frame)
            except (json.JSONDecodeError, RecursionError) as exc:
                raise MalformedMessage(f"invalid JSON: {exc}") from None
            self.handle(session, message)
        except BridgeError as exc:
            self.answer_failure(session, message, exc)
        except Exception as exc:  # a bug must not cost the client its connection, nor go unanswered
            log.exception("op %s failed", message.get("op") if isinstance(message, dict) else None)
            self.answer_failure(session, message, BridgeError(f"internal error: {exc}"))

    def handle(self, session: Session, message: Any) -> None:
        """Handle one parsed message (raises BridgeError for the caller to answer)."""
        if not isinstance(message, dict):
            raise MalformedMessage(f"a message must be a JSON object, got {type(message).__name__}")
        op = message.get("op")
        if not isinstance(op, str):
            raise MalformedMessage("a message needs a string field 'op'")
        handler = self._ops.get(op)
        if handler is None:
            raise UnknownOperation(f"unknown op '{op[:60]}'")
        if message.get("id") is not None and not isinstance(message["id"], (str, int)):
            raise InvalidField("field 'id' must be a string or an integer")
        fragment_size = optional(message, "fragment_size", int)
        if fragment_size is not None and op != p.OP_SUBSCRIBE:
            session.fragment_size = fragment_size if fragment_size > 0 else None
        result = handler(session, message)
        if asyncio.iscoroutine(result):
            self._spawn(session, message, result)

    def _spawn(self, session: Session, message: dict[str, Any], work: Any) -> None:
        # Slow work (service calls, goals) runs as a task, so it never blocks reading.
        async def guarded() -> None:
            try:
                await work
            except BridgeError as exc:
                self.answer_failure(session, message, exc)
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                log.exception("op %s failed", message.get("op"))
                self.answer_failure(session, message, BridgeError(f"internal error: {exc}"))

        tasks = self._tasks.setdefault(session.number, set())
        task = asyncio.get_running_loop().create_task(guarded())
        tasks.add(task)
        task.add_done_callback(tasks.discard)

    def answer_failure(self, session: Session, message: Any, error: BaseException) -> None:
        """Tell the client why its request failed, in the form its op expects."""
        op = message.get("op") if isinstance(message, dict) else None
        request_id = message.get("id") if isinstance(message, dict) else None
        reason = str(error) or type(error).__name__
        log.warning("session %d: %s (op %s, id %r) failed: %s", session.number, type(error).__name__, op, request_id, reason)
        if op == p.OP_CALL_SERVICE:
            answer: dict[str, Any] = {"op": p.OP_SERVICE_RESPONSE, "service": message.get("service"),
                                      "values": reason, "result": False}
            if request_id is not None:
                answer["id"] = request_id
            session.send(answer)
        elif op == p.OP_SEND_ACTION_GOAL:
            answer = {"op": p.OP_ACTION_RESULT, "action": message.get("action"), "values": reason,
                      "status": p.GOAL_STATUS_UNKNOWN, "result": False}
            if request_id is not None:
                answer["id"] = request_id
            session.send(answer)
        session.status("error", f"{op or 'message'}{'' if request_id is None else f' {request_id}'}: {reason}", request_id)

    def drop_session(self, session: Session) -> None:
        """Release everything a closed session held: tasks, registrations, fragments."""
        for task in self._tasks.pop(session.number, set()):
            task.cancel()
        self._fragments.pop(session.number, None)
        self.topics.drop_session(session)
        self.services.drop_session(session)
        if self.actions is not None:
            self.actions.drop_session(session)

    # --- topics --------------------------------------------------------------------------------
    def _topic(self, message: dict[str, Any]) -> str:
        topic = require(message, "topic", str)
        topic = topic if topic.startswith("/") else "/" + topic
        self.policy.topics.check(topic)
        return topic

    def _advertise(self, session: Session, message: dict[str, Any]) -> None:
        self.topics.advertise(session, self._topic(message), require(message, "type", str), message.get("id"),
                              latch=optional(message, "latch", bool, False),
                              queue_size=optional(message, "queue_size", int))

    def _unadvertise(self, session: Session, message: dict[str, Any]) -> None:
        self.topics.unadvertise(session, self._topic(message), message.get("id"))

    def _publish(self, session: Session, message: dict[str, Any]) -> None:
        topic = self._topic(message)
        if topic not in self.topics.publishers and message.get("type") is not None:
            self.topics.advertise(session, topic, optional(message, "type", str), None)
        self.topics.publish(session, topic, optional(message, "msg", dict, {}), optional(message, "latch", bool, False))

    def _subscribe(self, session: Session, message: dict[str, Any]) -> None:
        compression = optional(message, "compression", str, p.COMPRESSION_NONE)
        if compression not in p.COMPRESSIONS:
            raise InvalidField(f"compression must be one of {', '.join(p.COMPRESSIONS)}, got {compression!r}")
        throttle = optional(message, "throttle_rate", int, 0)
        queue_length = optional(message, "queue_length", int, 0)
        fragment_size = optional(message, "fragment_size", int)
        if throttle < 0 or queue_length < 0 or (fragment_size is not None and fragment_size <= 0):
            raise InvalidField("throttle_rate and queue_length must be >= 0, fragment_size > 0")
        self.topics.subscribe(session, self._topic(message), optional(message, "type", str), message.get("id"),
                              throttle_ms=throttle, queue_length=queue_length, fragment_size=fragment_size,
                              compression=compression)

    def _unsubscribe(self, session: Session, message: dict[str, Any]) -> None:
        self.topics.unsubscribe(session, self._topic(message), message.get("id"))

    # --- services ------------------------------------------------------------------------------
    def _service(self, message: dict[str, Any]) -> str:
        service = require(message, "service", str)
        service = service if service.startswith("/") else "/" + service
        self.policy.services.check(service)
        return service

    async def _call_service(self, session: Session, message: dict[str, Any]) -> None:
        service = self._service(message)
        args = message.get("args")
        if args is not None and not isinstance(args, (dict, list)):
            raise InvalidField(f"field 'args' must be an object or a list, got {type(args).__name__}")
        timeout = optional(message, "timeout", float)
        if self.rosapi.serves(service):
            values = await self.rosapi.call(service, args)
        else:
            values = await self.services.call(service, args, timeout)
        answer: dict[str, Any] = {"op": p.OP_SERVICE_RESPONSE, "service": message["service"], "values": values,
                                  "result": True}
        if message.get("id") is not None:
            answer["id"] = message["id"]
        session.send_frame(json.dumps(answer, separators=(",", ":")), optional(message, "fragment_size", int))

    def _service_response(self, session: Session, message: dict[str, Any]) -> None:
        self.services.respond(session, self._service(message), require(message, "id", str),
                              optional(message, "values", dict, {}), optional(message, "result", bool, True))

    def _advertise_service(self, session: Session, message: dict[str, Any]) -> None:
        self.services.advertise(session, self._service(message), require(message, "type", str))

    def _unadvertise_service(self, session: Session, message: dict[str, Any]) -> None:
        self.services.unadvertise(session, self._service(message))

    # --- protocol housekeeping -----------------------------------------------------------------
    def _set_level(self, session: Session, message: dict[str, Any]) -> None:
        level = require(message, "level", str)
        if level not in p.LEVELS:
            raise InvalidField(f"level must be one of {', '.join(p.LEVELS)}, got {level!r}")
        session.status_level = level

    def _auth_again(self, session: Session, message: dict[str, Any]) -> None:
        # Authentication happens before the first op is dispatched (server.py); a later or
        # unneeded auth message is harmless and acknowledged only via status.
        session.status("info", "already authenticated (or no authentication configured)", message.get("id"))

    def _fragment(self, session: Session, message: dict[str, Any]) -> None:
        fragment_id = require(message, "id", (str, int))
        data, num, total = require(message, "data", str), require(message, "num", int), require(message, "total", int)
        if total < 1 or not 0 <= num < total:
            raise InvalidField(f"fragment num {num} of total {total} is out of range")
        pending_all = self._fragments.setdefault(session.number, {})
        now = time.monotonic()
        for stale in [k for k, v in pending_all.items() if now - v.started > FRAGMENT_TIMEOUT_S]:
            del pending_all[stale]
        pending = pending_all.setdefault(fragment_id, PendingFragments(total, now))
        if pending.total != total:
            del pending_all[fragment_id]
            raise InvalidField(f"fragment {fragment_id!r}: total changed from {pending.total} to {total}")
        if num not in pending.parts:
            pending.size += len(data)
        pending.parts[num] = data
        if pending.size > self.policy.max_message_size:
            del pending_all[fragment_id]
            raise InvalidField(f"fragmented message {fragment_id!r} exceeds {self.policy.max_message_size} bytes")
        if len(pending.parts) == total:
            del pending_all[fragment_id]
            self.handle_frame(session, "".join(pending.parts[i] for i in range(total)))
