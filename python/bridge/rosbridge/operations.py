"""The op dispatch of rosbridge v2 and the one boundary where failures become answers.

:meth:`Bridge.handle` parses a frame, checks fields, names, allow-lists and quotas, and runs
the op's handler.  Any :class:`BridgeError` raised on the way is answered in the form the op's
client waits for: ``service_response`` with ``result: false`` and the reason as ``values`` for
``call_service``, ``action_result`` with ``result: false`` for ``send_action_goal``, and for
every op a ``status`` message naming op, id and reason (if the client asked for one with
``set_level``; refusals and quota errors even if it did not).  The connection stays up.

The answer to a failure is built only from values that always encode (:func:`.protocol.echo`,
:func:`.protocol.client_text`), so answering cannot fail in turn, and a client's input never
puts a traceback in the log: an unexpected exception (a bug) is logged, rate-limited per client,
and answered as an internal error without its text, which might name server files.
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import Callable
from typing import Any

from . import protocol as p
from .fragments import Reassembly
from .limits import Limits, Quotas
from .names import ros_name
from .protocol import (
    CONNECTION_STATS,
    BridgeError,
    InvalidField,
    MalformedMessage,
    OverQuota,
    Refused,
    UnknownOperation,
    client_text,
    echo,
    optional,
    require,
)
from .rosapi import Rosapi
from .security import Policy
from .services import Services
from .session import Session, SessionState, encode
from .topics import Topics

log = logging.getLogger(__name__)

MAX_SIZE_FIELD = 2**31 - 1


class Bridge:
    """Routes each client op to topics, services, actions or rosapi."""

    def __init__(
        self, topics: Topics, services: Services, actions: Any, policy: Policy, limits: Limits, quotas: Quotas
    ) -> None:
        self.topics = topics
        self.services = services
        self.actions = actions
        self.policy = policy
        self.limits = limits
        self.quotas = quotas
        self.rosapi = Rosapi(topics, services, policy)
        self.fragments = Reassembly(limits)
        self._tasks: dict[int, set[asyncio.Task[Any]]] = {}
        self._kept: set[asyncio.Task[Any]] = set()
        self._ops: dict[str, Callable[[Session, dict[str, Any]], Any]] = {
            p.OP_ADVERTISE: self._advertise,
            p.OP_UNADVERTISE: self._unadvertise,
            p.OP_PUBLISH: self._publish,
            p.OP_SUBSCRIBE: self._subscribe,
            p.OP_UNSUBSCRIBE: self._unsubscribe,
            p.OP_CALL_SERVICE: self._call_service,
            p.OP_SERVICE_RESPONSE: self._service_response,
            p.OP_ADVERTISE_SERVICE: self._advertise_service,
            p.OP_UNADVERTISE_SERVICE: self._unadvertise_service,
            p.OP_FRAGMENT: self._fragment,
            p.OP_SET_LEVEL: self._set_level,
            p.OP_AUTH: self._auth_again,
        }
        if actions is not None:
            self._ops.update(actions.operations())

    # --- the boundary --------------------------------------------------------------------------
    def handle_frame(self, session: Session, frame: str | bytes) -> None:
        """Parse one incoming frame and handle it; every failure is answered."""
        if session.state is SessionState.CLOSED:
            return
        session.traffic.messages_received += 1
        message: Any = None
        try:
            if isinstance(frame, bytes):
                raise MalformedMessage("binary frames are not accepted: send JSON text frames")
            message = _parse(frame)
            self.handle(session, message)
        except BridgeError as exc:
            self.answer_failure(session, message, exc)
        except Exception as exc:  # a bug must not cost the client its connection, nor go unanswered
            self.answer_failure(session, message, exc)

    def handle(self, session: Session, message: Any) -> None:
        """Handle one parsed message (raises BridgeError for the caller to answer)."""
        if not isinstance(message, dict):
            raise MalformedMessage(f"a message must be a JSON object, got {type(message).__name__}")
        op = message.get("op")
        if not isinstance(op, str):
            raise MalformedMessage("a message needs a string field 'op'")
        handler = self._ops.get(op)
        if handler is None:
            raise UnknownOperation(f"unknown op {client_text(op, 60)!r}")
        request_id = message.get("id")
        if request_id is not None and echo(request_id) is None:
            raise InvalidField("field 'id' must be a string or an integer of at most 64 bits")
        fragment_size = optional(message, "fragment_size", int, bounds=(self.limits.min_fragment_size, MAX_SIZE_FIELD))
        if fragment_size is not None and op != p.OP_SUBSCRIBE:
            session.fragment_size = fragment_size
        result = handler(session, message)
        if asyncio.iscoroutine(result):
            self._spawn(session, message, result, keep=op == p.OP_SEND_ACTION_GOAL)

    def _spawn(self, session: Session, message: dict[str, Any], work: Any, *, keep: bool) -> None:
        """Run slow work (service calls, goals) as a task, so it never blocks reading; unless
        ``keep``, the task is cancelled when the client disconnects (a goal's task is not: it
        cancels its goal and follows it to its end, see actions.py)."""

        async def guarded() -> None:
            try:
                await work
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                self.answer_failure(session, message, exc)

        tasks = self._kept if keep else self._tasks.setdefault(session.number, set())
        task = asyncio.get_running_loop().create_task(guarded())
        tasks.add(task)
        task.add_done_callback(tasks.discard)

    def answer_failure(self, session: Session, message: Any, error: BaseException) -> None:
        """Tell the client why its request failed, in the form its op expects."""
        fields = message if isinstance(message, dict) else {}
        op = echo(fields.get("op"))
        request_id = echo(fields.get("id"))
        if isinstance(error, BridgeError):
            reason = client_text(str(error) or type(error).__name__)
            session.log(logging.INFO, f"{type(error).__name__} (op {op}, id {request_id!r}): {reason}")
        else:
            reason = "internal error of the bridge (logged there)"
            session.log(
                logging.ERROR, f"op {op} id {request_id!r} failed: {type(error).__name__}: {error}", exc_info=error
            )
        answer: dict[str, Any] | None = None
        if op == p.OP_CALL_SERVICE:
            answer = {
                "op": p.OP_SERVICE_RESPONSE,
                "service": echo(fields.get("service")),
                "values": reason,
                "result": False,
            }
        elif op == p.OP_SEND_ACTION_GOAL:
            answer = {
                "op": p.OP_ACTION_RESULT,
                "action": echo(fields.get("action")),
                "values": reason,
                "status": p.GOAL_STATUS_UNKNOWN,
                "result": False,
            }
        if answer is not None:
            if request_id is not None:
                answer["id"] = request_id
            session.send(answer)
        label = f"{op if isinstance(op, str) else 'message'}{'' if request_id is None else f' {request_id}'}"
        session.status(
            "error", f"{client_text(label, 120)}: {reason}", request_id, always=isinstance(error, (Refused, OverQuota))
        )

    def drop_session(self, session: Session) -> None:
        """Release everything a closed session held: tasks, registrations, fragments, quotas."""
        for task in self._tasks.pop(session.number, set()):
            task.cancel()
        self.fragments.forget(session.number)
        self.topics.drop_session(session)
        self.services.drop_session(session)
        if self.actions is not None:
            self.actions.drop_session(session)
        self.quotas.forget(session.number)

    # --- topics --------------------------------------------------------------------------------
    def _topic(self, message: dict[str, Any]) -> str:
        topic = ros_name("topic", require(message, "topic", str))
        self.policy.topics.check(topic)
        return topic

    def _advertise(self, session: Session, message: dict[str, Any]) -> None:
        self.topics.advertise(
            session,
            self._topic(message),
            require(message, "type", str),
            echo(message.get("id")),
            latch=optional(message, "latch", bool, False),
            queue_size=optional(message, "queue_size", int, bounds=(0, 100_000)),
        )

    def _unadvertise(self, session: Session, message: dict[str, Any]) -> None:
        self.topics.unadvertise(session, self._topic(message), echo(message.get("id")))

    def _publish(self, session: Session, message: dict[str, Any]) -> None:
        topic = self._topic(message)
        type_name = optional(message, "type", str)
        latch = optional(message, "latch", bool, False)
        if topic not in self.topics.publishers and type_name is not None:
            self.topics.advertise(session, topic, type_name, None)
        self.topics.publish(session, topic, optional(message, "msg", dict, {}), latch)

    def _subscribe(self, session: Session, message: dict[str, Any]) -> None:
        compression = optional(message, "compression", str, p.COMPRESSION_NONE)
        if compression not in p.COMPRESSIONS:
            raise InvalidField(
                f"compression must be one of {', '.join(p.COMPRESSIONS)}, got {client_text(compression, 40)!r}"
            )
        throttle = optional(message, "throttle_rate", int, 0, bounds=(0, 86_400_000))
        queue_length = optional(message, "queue_length", int, 0, bounds=(0, 100_000))
        fragment_size = optional(message, "fragment_size", int, bounds=(self.limits.min_fragment_size, MAX_SIZE_FIELD))
        self.topics.subscribe(
            session,
            self._topic(message),
            optional(message, "type", str),
            echo(message.get("id")),
            throttle_ms=throttle,
            queue_length=queue_length,
            fragment_size=fragment_size,
            compression=compression,
        )

    def _unsubscribe(self, session: Session, message: dict[str, Any]) -> None:
        self.topics.unsubscribe(session, self._topic(message), echo(message.get("id")))

    # --- services ------------------------------------------------------------------------------
    def _service(self, message: dict[str, Any]) -> str:
        service = ros_name("service", require(message, "service", str))
        self.policy.services.check(service)
        return service

    def _call_service(self, session: Session, message: dict[str, Any]) -> Any:
        service = self._service(message)
        args = message.get("args")
        if args is not None and not isinstance(args, (dict, list)):
            raise InvalidField(f"field 'args' must be an object or a list, got {type(args).__name__}")
        timeout = optional(message, "timeout", float, bounds=(0.0, 86_400.0))
        answer_fragment_size = optional(
            message, "fragment_size", int, bounds=(self.limits.min_fragment_size, MAX_SIZE_FIELD)
        )
        self.quotas.calls.take(session.number)
        return self._answer_call(session, message, service, args, timeout, answer_fragment_size)

    async def _answer_call(
        self,
        session: Session,
        message: dict[str, Any],
        service: str,
        args: Any,
        timeout: float | None,
        fragment_size: int | None,
    ) -> None:
        try:
            if service == CONNECTION_STATS:
                values = {"connection": session.number, "peer": session.peer, **session.traffic.as_dict()}
            elif self.rosapi.serves(service):
                values = await self.rosapi.call(service, args)
            else:
                values = await self.services.call(service, args, timeout)
        finally:
            self.quotas.calls.give(session.number)
        answer: dict[str, Any] = {
            "op": p.OP_SERVICE_RESPONSE,
            "service": echo(message["service"]),
            "values": values,
            "result": True,
        }
        request_id = echo(message.get("id"))
        if request_id is not None:
            answer["id"] = request_id
        session.send_frame(encode(answer), fragment_size)

    def _service_response(self, session: Session, message: dict[str, Any]) -> None:
        result = optional(message, "result", bool, True)
        # a failed request's values say why, as text or anything else (rosbridge sends a string)
        values = optional(message, "values", dict, {}) if result else message.get("values")
        self.services.respond(session, self._service(message), require(message, "id", str), values, result)

    def _advertise_service(self, session: Session, message: dict[str, Any]) -> None:
        self.services.advertise(session, self._service(message), require(message, "type", str))

    def _unadvertise_service(self, session: Session, message: dict[str, Any]) -> None:
        self.services.unadvertise(session, self._service(message))

    # --- protocol housekeeping -----------------------------------------------------------------
    def _set_level(self, session: Session, message: dict[str, Any]) -> None:
        level = require(message, "level", str)
        if level not in p.LEVELS:
            raise InvalidField(f"level must be one of {', '.join(p.LEVELS)}, got {client_text(level, 40)!r}")
        session.status_level = level

    def _auth_again(self, session: Session, message: dict[str, Any]) -> None:
        # Authentication happens before the first op is dispatched (server.py); a later or
        # unneeded auth message is harmless and acknowledged only via status.
        session.status("info", "already authenticated (or no authentication configured)", echo(message.get("id")))

    def _fragment(self, session: Session, message: dict[str, Any]) -> None:
        fragment_id = require(message, "id", (str, int))
        data = require(message, "data", str)
        num = require(message, "num", int, bounds=(0, MAX_SIZE_FIELD))
        total = require(message, "total", int, bounds=(1, MAX_SIZE_FIELD))
        whole = self.fragments.add(session.number, fragment_id, data, num, total)
        if whole is not None:
            inner = _parse(whole)
            if isinstance(inner, dict) and inner.get("op") == p.OP_FRAGMENT:
                raise InvalidField("a reassembled message must not be a fragment itself")
            self.handle(session, inner)


def _parse(text: str) -> Any:
    """The JSON value of a frame; :class:`MalformedMessage` for anything else."""
    try:
        return json.loads(text)
    except RecursionError:
        raise MalformedMessage("invalid JSON: nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError, and integers beyond Python's 4300-digit limit
        detail = str(exc) if isinstance(exc, json.JSONDecodeError) else "a number has too many digits"
        raise MalformedMessage(f"invalid JSON: {client_text(detail, 120)}") from None
