"""ROS 2 actions both ways: clients sending goals, and clients serving actions.

Sending (``send_action_goal``): one ``ActionClient`` per (action, type) on the server node,
shared by every goal to it and destroyed :data:`CLIENT_LINGER_S` after its last goal ended (at
most :data:`MAX_CLIENTS` exist: a client sending goals to ever new action names cannot make the
bridge hold ever more of them).  No client is made for an action no server offers.  Feedback
is forwarded as ``action_feedback`` when the goal asked for it, and the outcome as
``action_result`` with the goal's final status (``result`` true only for SUCCEEDED).  A
rejected goal or a missing server is answered with ``result: false`` too.
``cancel_action_goal`` names the goal by the id the client gave it.

**Disconnect policy: the goals of a client that disconnects are cancelled**, also those not
yet accepted (cancelled as soon as they are).  A goal nobody can follow any more must not keep
moving a robot; commands that must survive a link drop go through the habitat's command ledger
(``caretaker ledger``), not through a goal left running.  Each goal is followed by its own
task until the action server reports its end (or :data:`ORPHAN_WAIT_S` after the cancel), so
its client stays alive and counted (``--max-goals``) as long as the goal is.

Serving (``advertise_action``): an ``ActionServer`` whose execute coroutine forwards each goal
to the client as ``send_action_goal`` (id ``action_goal:<action>:<n>``, ``feedback: true``),
publishes the client's ``action_feedback``, forwards ROS cancel requests as
``cancel_action_goal``, and ends the goal as the client's ``action_result`` says (status 4
succeeded, 5 canceled, anything else or ``result: false`` aborted).  A serving client that
disconnects aborts its goals; the ROS server stays :data:`RESULT_LINGER_S` after their end
(see :class:`ServedAction`), so each of their results reaches its caller.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import rclpy.task
from rclpy.action import ActionClient, ActionServer, CancelResponse

from . import protocol as p
from .conversion import dict_to_message, load_type, message_to_dict
from .limits import Quotas
from .names import ros_name
from .protocol import ActionFailed, InvalidField, OverQuota, echo, optional, require
from .ros_thread import RosThread
from .security import AllowList
from .session import Session, SessionState

log = logging.getLogger(__name__)

SERVER_WAIT_S = 1.0
CLIENT_LINGER_S = 30.0
"""An action client outlives its last goal this long: the next goal to the same action then
needs no new discovery."""
MAX_CLIENTS = 64
ORPHAN_WAIT_S = 60.0
"""How long the bridge follows a cancelled goal of a disconnected client before it lets go."""
RESULT_LINGER_S = 10.0
"""A served action nobody serves any more keeps its ROS server this long after its last goal
(see :class:`ServedAction`): the server answers a result request only while it exists."""


@dataclass
class ServedAction:
    """The bridge's ROS action server of one action name, executed by one client at a time.

    It outlives the clients that serve it: withdrawn, it is destroyed :data:`RESULT_LINGER_S`
    after its last goal ended, so that a caller's late request for a result is still answered,
    and a client that advertises the action again meanwhile takes it over (rather than a second
    server of the same name answering beside it).
    """

    name: str
    action_cls: Any
    server: Any = None
    # Set only on the ros-servers thread, which decides each goal's fate:
    provider: ProvidedAction | None = None
    """The advertisement whose client executes new goals; None while nobody serves it."""
    goals: dict[str, tuple[Any, rclpy.task.Future, ProvidedAction]] = field(default_factory=dict)
    """Goals in flight by id: their handle, their outcome, the advertisement executing them."""
    counter: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    destroyed: bool = False
    idle_turn: int = 0
    """Counts the times it fell idle: only the retirement planned at the latest may happen."""


@dataclass
class ProvidedAction:
    """One client's advertisement of an action."""

    served: ServedAction
    session: Session


@dataclass
class SharedClient:
    """An action client and the number of goals using it."""

    client: ActionClient
    users: int = 0
    expiry: asyncio.TimerHandle | None = None


@dataclass
class SentGoal:
    """A goal a client sent, from its request until its end; touched only on the event loop."""

    session: Session
    handle: Any = None
    """The goal handle once the action server accepted the goal."""
    cancel_wanted: bool = False
    """Cancel as soon as accepted (asked before acceptance, or the client disconnected)."""


class Actions:
    """Action goals sent by clients and actions served by clients."""

    def __init__(
        self, ros: RosThread, allow: AllowList, quotas: Quotas, services_graph: Callable[[], dict[str, str]]
    ) -> None:
        self.ros = ros
        self.allow = allow
        self.quotas = quotas
        self._graph = services_graph
        self._clients: dict[tuple[str, str], SharedClient] = {}  # least recently used first
        self._goals: dict[tuple[int, Any], SentGoal] = {}
        self.provided: dict[str, ProvidedAction] = {}
        self._servers: dict[str, ServedAction] = {}

    def operations(self) -> dict[str, Callable[[Session, dict[str, Any]], Any]]:
        """The ops this module serves, for the bridge's dispatch table."""
        return {
            p.OP_SEND_ACTION_GOAL: self._send_goal,
            p.OP_CANCEL_ACTION_GOAL: self._cancel_goal,
            p.OP_ADVERTISE_ACTION: self._advertise,
            p.OP_UNADVERTISE_ACTION: self._unadvertise,
            p.OP_ACTION_FEEDBACK: self._feedback,
            p.OP_ACTION_RESULT: self._result,
        }

    def _action(self, message: dict[str, Any]) -> str:
        action = ros_name("action", require(message, "action", str))
        self.allow.check(action)
        return action

    # --- clients sending goals -----------------------------------------------------------------
    def _send_goal(self, session: Session, message: dict[str, Any]) -> Any:
        action = self._action(message)
        type_name = require(message, "action_type", str)
        action_cls = load_type(type_name, "action")
        goal = dict_to_message(action_cls.Goal, optional(message, "args", dict, {}), "args")
        wants_feedback = optional(message, "feedback", bool, False)
        goal_id = echo(message.get("id"))
        key = (session.number, goal_id if goal_id is not None else object())
        if key in self._goals:
            raise InvalidField(f"a goal with id {goal_id!r} of this client is still running")
        self.quotas.goals.take(session.number)
        record = self._goals[key] = SentGoal(session)
        return self._follow_goal(record, key, action, type_name, action_cls, goal, wants_feedback, message)

    async def _follow_goal(
        self,
        record: SentGoal,
        key: tuple[int, Any],
        action: str,
        type_name: str,
        action_cls: Any,
        goal: Any,
        wants_feedback: bool,
        message: dict[str, Any],
    ) -> None:
        # Not cancelled when the client disconnects (see the module doc): it cancels the goal.
        session = record.session
        reply: dict[str, Any] = {"action": echo(message["action"])}
        if echo(message.get("id")) is not None:
            reply["id"] = echo(message.get("id"))
        shared = None
        try:
            shared = await self._client_for(action, type_name, action_cls)

            def forward_feedback(feedback: Any) -> None:
                values = message_to_dict(feedback.feedback)
                self.ros.deliver(session.send, {"op": p.OP_ACTION_FEEDBACK, **reply, "values": values})

            handle = await self.ros.ask(
                shared.client.send_goal_async, goal, feedback_callback=forward_feedback if wants_feedback else None
            )
            if not handle.accepted:
                raise ActionFailed(f"the action server of {action} rejected the goal")
            record.handle = handle
            if record.cancel_wanted or session.state is SessionState.CLOSED:
                self._cancel(record)
            if session.state is SessionState.CLOSED:
                outcome = await asyncio.wait_for(self.ros.ask(handle.get_result_async), ORPHAN_WAIT_S)
            else:
                outcome = await self.ros.ask(handle.get_result_async)
        except TimeoutError:
            log.warning(
                "a cancelled goal of a disconnected client on %s did not end within %.0f s", action, ORPHAN_WAIT_S
            )
            return
        finally:
            del self._goals[key]
            self.quotas.goals.give(session.number)
            if shared is not None:
                self._release(action, type_name, shared)
        session.send(
            {
                "op": p.OP_ACTION_RESULT,
                **reply,
                "values": message_to_dict(outcome.result),
                "status": outcome.status,
                "result": outcome.status == p.GOAL_STATUS_SUCCEEDED,
            }
        )

    async def _client_for(self, action: str, type_name: str, action_cls: Any) -> SharedClient:
        """The shared client of (``action``, ``type_name``) once its server is ready, counted as used."""
        key = (action, type_name)
        shared = self._clients.pop(key, None)
        if shared is None:
            deadline = asyncio.get_running_loop().time() + SERVER_WAIT_S
            while f"{action}/_action/send_goal" not in self._graph():
                if asyncio.get_running_loop().time() > deadline:
                    raise ActionFailed(f"Action server {action} is not available")
                await asyncio.sleep(0.02)  # rclpy offers no graph-change event to await here
            shared = self._clients.pop(key, None) or SharedClient(self._new_client(action_cls, action))
        self._clients[key] = shared  # now the most recently used
        shared.users += 1
        if shared.expiry is not None:
            shared.expiry.cancel()
            shared.expiry = None
        try:
            deadline = asyncio.get_running_loop().time() + SERVER_WAIT_S
            while not shared.client.server_is_ready():
                if asyncio.get_running_loop().time() > deadline:
                    raise ActionFailed(f"Action server {action} is not available")
                await asyncio.sleep(0.01)
        except BaseException:
            self._release(action, type_name, shared)
            raise
        return shared

    def _new_client(self, action_cls: Any, action: str) -> ActionClient:
        idle = [key for key, shared in self._clients.items() if not shared.users]
        for key in idle[: max(0, len(self._clients) + 1 - MAX_CLIENTS)]:
            self._destroy_client(key, self._clients[key])
        if len(self._clients) >= MAX_CLIENTS:
            raise OverQuota(f"too many actions with goals in flight on this bridge (limit {MAX_CLIENTS})")
        return ActionClient(self.ros.server_node, action_cls, action)

    def _release(self, action: str, type_name: str, shared: SharedClient) -> None:
        shared.users -= 1
        if shared.users == 0 and self._clients.get((action, type_name)) is shared:
            shared.expiry = asyncio.get_running_loop().call_later(
                CLIENT_LINGER_S, self._destroy_client, (action, type_name), shared
            )

    def _destroy_client(self, key: tuple[str, str], shared: SharedClient) -> None:
        if shared.users or self._clients.get(key) is not shared:
            return
        del self._clients[key]
        if shared.expiry is not None:
            shared.expiry.cancel()
        self.ros.on_server_thread(shared.client.destroy)  # where its executor uses it

    def _cancel(self, record: SentGoal) -> None:
        if record.handle is None:
            record.cancel_wanted = True
        else:
            self.ros.on_server_thread(record.handle.cancel_goal_async)  # its action_result then reports CANCELED

    def _cancel_goal(self, session: Session, message: dict[str, Any]) -> None:
        self._action(message)
        goal_id = require(message, "id", (str, int))
        record = self._goals.get((session.number, goal_id))
        if record is None:
            raise InvalidField(f"no running goal with id {echo(goal_id)!r} from this client")
        self._cancel(record)

    # --- clients serving actions ---------------------------------------------------------------
    def _advertise(self, session: Session, message: dict[str, Any]) -> None:
        action = self._action(message)
        action_cls = load_type(require(message, "type", str), "action")
        self.quotas.advertisements.take(session.number)
        served = self._servers.get(action)
        if served is None or served.action_cls is not action_cls:
            fresh = ServedAction(action, action_cls)
            try:
                self._serve(fresh)
            except Exception as exc:
                self.quotas.advertisements.give(session.number)
                raise InvalidField(f"cannot advertise action {action}: {type(exc).__name__}") from None
            if served is not None:  # another type under this name: the old server retires
                self.ros.on_server_thread(self._take_over, served, None, "replaced by a newer advertise_action")
            served = self._servers[action] = fresh
        previous = self.provided.get(action)
        if previous is not None:
            self.quotas.advertisements.give(previous.session.number)
        provided = self.provided[action] = ProvidedAction(served, session)
        self.ros.on_server_thread(self._take_over, served, provided, "replaced by a newer advertise_action")

    def _serve(self, served: ServedAction) -> None:
        """Give ``served`` a new ROS action server."""
        action = served.name

        async def execute_callback(goal_handle: Any) -> Any:
            return await self._execute(served, goal_handle)

        def cancel_callback(goal_handle: Any) -> CancelResponse:
            for goal_id, (handle, _, provided) in served.goals.items():
                if handle is goal_handle:
                    self.ros.deliver(
                        provided.session.send, {"op": p.OP_CANCEL_ACTION_GOAL, "id": goal_id, "action": action}
                    )
            return CancelResponse.ACCEPT

        served.server = ActionServer(
            self.ros.server_node, served.action_cls, action, execute_callback, cancel_callback=cancel_callback
        )

    def _unadvertise(self, session: Session, message: dict[str, Any]) -> None:
        provided = self.provided.get(self._action(message))
        if provided is None or provided.session is not session:
            raise InvalidField(f"action {echo(message['action'])} is not advertised by this client")
        self._withdraw(provided, "unadvertised by its client")

    async def _execute(self, served: ServedAction, goal_handle: Any) -> Any:
        # Runs on the ros-servers thread as an executor task.
        provided = served.provider
        if provided is None:  # withdrawn, and nobody took it over (yet)
            goal_handle.abort()
            self._retire_when_idle(served)
            return served.action_cls.Result()
        goal_id = f"action_goal:{served.name}:{next(served.counter)}"
        outcome = rclpy.task.Future()
        served.goals[goal_id] = (goal_handle, outcome, provided)
        self.ros.deliver(
            provided.session.send,
            {
                "op": p.OP_SEND_ACTION_GOAL,
                "id": goal_id,
                "action": served.name,
                "action_type": _type_name(served.action_cls),
                "args": message_to_dict(goal_handle.request),
                "feedback": True,
            },
        )
        try:
            status, result = await outcome
        except Exception as exc:
            log.error("goal %s of %s aborted: %s", goal_id, served.name, exc)
            goal_handle.abort()
            return served.action_cls.Result()
        finally:
            served.goals.pop(goal_id, None)
            self._retire_when_idle(served)
        if status == p.GOAL_STATUS_SUCCEEDED:
            goal_handle.succeed()
        elif status == p.GOAL_STATUS_CANCELED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        return result

    def _goal_of(self, session: Session, message: dict[str, Any]) -> tuple[ServedAction, str]:
        provided = self.provided.get(self._action(message))
        goal_id = require(message, "id", str)
        goal = provided.served.goals.get(goal_id) if provided is not None else None
        if provided is None or provided.session is not session or goal is None or goal[2] is not provided:
            raise InvalidField(
                f"no goal {echo(goal_id)!r} of action {echo(message['action'])} is running for this client"
            )
        return provided.served, goal_id

    def _feedback(self, session: Session, message: dict[str, Any]) -> None:
        served, goal_id = self._goal_of(session, message)
        feedback = dict_to_message(served.action_cls.Feedback, optional(message, "values", dict, {}), "values")
        served.goals[goal_id][0].publish_feedback(feedback)

    def _result(self, session: Session, message: dict[str, Any]) -> None:
        served, goal_id = self._goal_of(session, message)
        succeeded = optional(message, "result", bool, True)
        status = optional(
            message, "status", int, p.GOAL_STATUS_SUCCEEDED if succeeded else p.GOAL_STATUS_ABORTED, bounds=(0, 6)
        )
        if not succeeded:
            status = p.GOAL_STATUS_ABORTED if status == p.GOAL_STATUS_SUCCEEDED else status
        values = optional(message, "values", dict, {})
        result = dict_to_message(served.action_cls.Result, values, "values")
        served.goals[goal_id][1].set_result((status, result))
        self.ros.server_executor.wake()

    def _withdraw(self, provided: ProvidedAction, reason: str) -> None:
        name = provided.served.name
        if self.provided.get(name) is provided:
            del self.provided[name]
            self.quotas.advertisements.give(provided.session.number)
            self.ros.on_server_thread(self._take_over, provided.served, None, reason, provided)

    def _take_over(
        self,
        served: ServedAction,
        provided: ProvidedAction | None,
        reason: str,
        only_from: ProvidedAction | None = None,
    ) -> None:
        """On the ros-servers thread, which decides each goal's fate: ``provided`` executes the
        new goals of ``served`` from now on (``None``: nobody does). The goals of the client that
        served it so far end, aborted with ``reason``. With ``only_from``, nothing changes unless
        that is still the one serving (a withdrawal that a newer advertisement overtook)."""
        if only_from is not None and served.provider is not only_from:
            return
        for _, outcome, owner in served.goals.values():
            if owner is served.provider and not outcome.done():
                outcome.set_exception(ActionFailed(f"action {served.name} {reason}"))
        served.provider = provided
        if served.destroyed and provided is not None:  # retired meanwhile: serve anew
            self._serve(served)
            served.destroyed = False
        self._retire_when_idle(served)

    def _retire_when_idle(self, served: ServedAction) -> None:
        """On the ros-servers thread: destroy a server nobody serves :data:`RESULT_LINGER_S` after
        its last goal ended, if nobody took it over meanwhile."""
        if served.provider is None and not served.goals and not served.destroyed:
            served.idle_turn += 1
            self.ros.deliver(
                self.ros.loop.call_later,
                RESULT_LINGER_S,
                self.ros.on_server_thread,
                self._retire,
                served,
                served.idle_turn,
            )

    def _retire(self, served: ServedAction, idle_turn: int) -> None:
        # On the ros-servers thread, whose executor waits on the server: destroyed from any other
        # thread, it could vanish between the executor collecting it and adding it to a wait set
        # ("RCLError: action server pointer is invalid").
        if served.idle_turn == idle_turn and served.provider is None and not served.goals and not served.destroyed:
            served.destroyed = True
            served.server.destroy()
            self.ros.deliver(self._forget, served)

    def _forget(self, served: ServedAction) -> None:
        if self._servers.get(served.name) is served and served.destroyed:
            del self._servers[served.name]

    def drop_session(self, session: Session) -> None:
        """Withdraw the actions a closed session served and cancel the goals it sent (their
        tasks go on until the goals end: see the module doc)."""
        for provided in [a for a in self.provided.values() if a.session is session]:
            self._withdraw(provided, "lost its client")
        for key, record in self._goals.items():
            if key[0] == session.number:
                self._cancel(record)


def _type_name(action_cls: Any) -> str:
    return f"{action_cls.__module__.split('.')[0]}/action/{action_cls.__name__}"
