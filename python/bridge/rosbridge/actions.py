"""ROS 2 actions both ways: clients sending goals, and clients serving actions.

Sending (``send_action_goal``): one cached ``ActionClient`` per action on the server node;
feedback is forwarded as ``action_feedback`` when the goal asked for it, and the outcome as
``action_result`` with the goal's final status (``result`` true only for SUCCEEDED).  A
rejected goal or a missing server is answered with ``result: false`` too.
``cancel_action_goal`` names the goal by the id the client gave it.

Serving (``advertise_action``): an ``ActionServer`` whose execute coroutine forwards each goal
to the client as ``send_action_goal`` (id ``action_goal:<action>:<n>``, ``feedback: true``),
publishes the client's ``action_feedback``, forwards ROS cancel requests as
``cancel_action_goal``, and ends the goal as the client's ``action_result`` says (status 4
succeeded, 5 canceled, anything else or ``result: false`` aborted).
"""

from __future__ import annotations

import asyncio
import itertools
import logging
from dataclasses import dataclass, field
from typing import Any, Callable

import rclpy.task
from rclpy.action import ActionClient, ActionServer, CancelResponse

from . import protocol as p
from .conversion import dict_to_message, load_type, message_to_dict
from .protocol import ActionFailed, InvalidField, optional, require
from .ros_thread import RosThread
from .security import AllowList
from .session import Session

log = logging.getLogger(__name__)

SERVER_WAIT_S = 1.0


@dataclass
class ProvidedAction:
    """A ROS action server whose goals a WebSocket client executes."""

    name: str
    action_cls: Any
    session: Session
    server: Any = None
    goals: dict[str, tuple[Any, rclpy.task.Future]] = field(default_factory=dict)
    counter: itertools.count = field(default_factory=lambda: itertools.count(1))


class Actions:
    """Action goals sent by clients and actions served by clients."""

    def __init__(self, ros: RosThread, allow: AllowList) -> None:
        self.ros = ros
        self.allow = allow
        self._clients: dict[tuple[str, str], ActionClient] = {}
        # (session, client goal id) -> goal handle, or None until the server accepted the goal
        self._goals: dict[tuple[int, Any], Any] = {}
        self._early_cancels: set[tuple[int, Any]] = set()  # cancelled before the server accepted
        self.provided: dict[str, ProvidedAction] = {}

    def operations(self) -> dict[str, Callable[[Session, dict[str, Any]], Any]]:
        """The ops this module serves, for the bridge's dispatch table."""
        return {p.OP_SEND_ACTION_GOAL: self._send_goal, p.OP_CANCEL_ACTION_GOAL: self._cancel_goal,
                p.OP_ADVERTISE_ACTION: self._advertise, p.OP_UNADVERTISE_ACTION: self._unadvertise,
                p.OP_ACTION_FEEDBACK: self._feedback, p.OP_ACTION_RESULT: self._result}

    def _action(self, message: dict[str, Any]) -> str:
        action = require(message, "action", str)
        action = action if action.startswith("/") else "/" + action
        self.allow.check(action)
        return action

    # --- clients sending goals -----------------------------------------------------------------
    async def _send_goal(self, session: Session, message: dict[str, Any]) -> None:
        action = self._action(message)
        type_name = require(message, "action_type", str)
        action_cls = load_type(type_name, "action")
        goal = dict_to_message(action_cls.Goal, optional(message, "args", dict, {}), "args")
        client = self._clients.get((action, type_name))
        if client is None:
            client = self._clients[(action, type_name)] = ActionClient(self.ros.server_node, action_cls, action)
        deadline = asyncio.get_running_loop().time() + SERVER_WAIT_S
        while not client.server_is_ready():
            if asyncio.get_running_loop().time() > deadline:
                raise ActionFailed(f"Action server {action} is not available")
            await asyncio.sleep(0.01)
        goal_id = message.get("id")
        reply: dict[str, Any] = {"action": message["action"]}
        if goal_id is not None:
            reply["id"] = goal_id
        feedback_callback = None
        if optional(message, "feedback", bool, False):
            def feedback_callback(feedback: Any) -> None:
                values = message_to_dict(feedback.feedback)
                self.ros.deliver(session.send, {"op": p.OP_ACTION_FEEDBACK, **reply, "values": values})
        key = (session.number, goal_id)
        self._goals[key] = None
        try:
            # Feedback may reach the client before the acceptance reaches the bridge, so a cancel
            # can arrive before the handle: it is kept and sent once the goal is accepted.
            handle = await self.ros.ask(client.send_goal_async, goal, feedback_callback=feedback_callback)
            if not handle.accepted:
                raise ActionFailed(f"the action server of {action} rejected the goal")
            self._goals[key] = handle
            if key in self._early_cancels:
                self.ros.on_server_thread(handle.cancel_goal_async)
            outcome = await self.ros.ask(handle.get_result_async)
        finally:
            self._goals.pop(key, None)
            self._early_cancels.discard(key)
        session.send({"op": p.OP_ACTION_RESULT, **reply, "values": message_to_dict(outcome.result),
                      "status": outcome.status, "result": outcome.status == p.GOAL_STATUS_SUCCEEDED})

    def _cancel_goal(self, session: Session, message: dict[str, Any]) -> None:
        self._action(message)
        goal_id = require(message, "id", (str, int))
        key = (session.number, goal_id)
        if key not in self._goals:
            raise InvalidField(f"no running goal with id {goal_id!r} from this client")
        if self._goals[key] is None:
            self._early_cancels.add(key)
        else:
            self.ros.on_server_thread(self._goals[key].cancel_goal_async)  # its action_result then reports CANCELED

    # --- clients serving actions ---------------------------------------------------------------
    def _advertise(self, session: Session, message: dict[str, Any]) -> None:
        action = self._action(message)
        action_cls = load_type(require(message, "type", str), "action")
        if action in self.provided:
            self._withdraw(self.provided[action], "replaced by a newer advertise_action")
        provided = ProvidedAction(action, action_cls, session)

        async def execute_callback(goal_handle: Any) -> Any:
            return await self._execute(provided, goal_handle)

        def cancel_callback(goal_handle: Any) -> CancelResponse:
            for goal_id, (handle, _) in provided.goals.items():
                if handle is goal_handle:
                    self.ros.deliver(session.send, {"op": p.OP_CANCEL_ACTION_GOAL, "id": goal_id, "action": action})
            return CancelResponse.ACCEPT

        provided.server = ActionServer(self.ros.server_node, action_cls, action, execute_callback,
                                       cancel_callback=cancel_callback)
        self.provided[action] = provided

    def _unadvertise(self, session: Session, message: dict[str, Any]) -> None:
        provided = self.provided.get(self._action(message))
        if provided is None or provided.session is not session:
            raise InvalidField(f"action {message['action']} is not advertised by this client")
        self._withdraw(provided, "unadvertised by its client")

    async def _execute(self, provided: ProvidedAction, goal_handle: Any) -> Any:
        # Runs on the ros-servers thread as an executor task.
        goal_id = f"action_goal:{provided.name}:{next(provided.counter)}"
        outcome = rclpy.task.Future()
        provided.goals[goal_id] = (goal_handle, outcome)
        self.ros.deliver(provided.session.send, {
            "op": p.OP_SEND_ACTION_GOAL, "id": goal_id, "action": provided.name,
            "action_type": _type_name(provided.action_cls), "args": message_to_dict(goal_handle.request),
            "feedback": True})
        try:
            status, result = await outcome
        except Exception as exc:
            log.error("goal %s of %s aborted: %s", goal_id, provided.name, exc)
            goal_handle.abort()
            return provided.action_cls.Result()
        finally:
            provided.goals.pop(goal_id, None)
        if status == p.GOAL_STATUS_SUCCEEDED:
            goal_handle.succeed()
        elif status == p.GOAL_STATUS_CANCELED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        return result

    def _goal_of(self, session: Session, message: dict[str, Any]) -> tuple[ProvidedAction, str]:
        provided = self.provided.get(self._action(message))
        goal_id = require(message, "id", str)
        if provided is None or provided.session is not session or goal_id not in provided.goals:
            raise InvalidField(f"no goal {goal_id!r} of action {message['action']} is running for this client")
        return provided, goal_id

    def _feedback(self, session: Session, message: dict[str, Any]) -> None:
        provided, goal_id = self._goal_of(session, message)
        feedback = dict_to_message(provided.action_cls.Feedback, optional(message, "values", dict, {}), "values")
        provided.goals[goal_id][0].publish_feedback(feedback)

    def _result(self, session: Session, message: dict[str, Any]) -> None:
        provided, goal_id = self._goal_of(session, message)
        succeeded = optional(message, "result", bool, True)
        status = optional(message, "status", int, p.GOAL_STATUS_SUCCEEDED if succeeded else p.GOAL_STATUS_ABORTED)
        if not succeeded:
            status = p.GOAL_STATUS_ABORTED if status == p.GOAL_STATUS_SUCCEEDED else status
        values = optional(message, "values", dict, {})
        result = dict_to_message(provided.action_cls.Result, values, "values")
        provided.goals[goal_id][1].set_result((status, result))
        self.ros.server_executor.wake()

    def _withdraw(self, provided: ProvidedAction, reason: str) -> None:
        if self.provided.get(provided.name) is provided:
            del self.provided[provided.name]
        for _, outcome in provided.goals.values():
            if not outcome.done():
                outcome.set_exception(ActionFailed(f"action {provided.name} {reason}"))
        self.ros.server_executor.wake()
        provided.server.destroy()

    def drop_session(self, session: Session) -> None:
        """Withdraw the actions a closed session served and cancel the goals it sent."""
        for provided in [a for a in self.provided.values() if a.session is session]:
            self._withdraw(provided, "lost its client")
        for key in [k for k in self._goals if k[0] == session.number]:
            self.ros.on_server_thread(self._goals.pop(key).cancel_goal_async)


def _type_name(action_cls: Any) -> str:
    return f"{action_cls.__module__.split('.')[0]}/action/{action_cls.__name__}"
