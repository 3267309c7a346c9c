"""The ``services`` and ``actions`` profiles: the suite serves what it calls, through the server."""

from __future__ import annotations

import time
from typing import Any

from .outcome import Outcome
from .runner import Case, CaseContext, Verdict
from .session import Conversation, NotAnswered, op_is
from .steps import call_served, new_id

__all__ = ["ACTION_TYPE", "CASES"]

SET_BOOL = "std_srvs/srv/SetBool"
ACTION_TYPE = "caretaker_sim_msgs/action/FollowJointTrajectory"
GOAL = {"trajectory": {"joint_names": ["joint_a"], "points": []}, "goal_tolerance": 0.0}
FEEDBACK = {"joint_names": ["joint_a"], "desired": [0.5], "actual": [0.25], "time_from_start": 0.5}


async def _serving(context: CaseContext, leaf: str) -> tuple[Conversation, Conversation, str]:
    server, caller = await context.connect_pair("server", "caller")
    service = context.name(leaf)
    await server.send({"op": "advertise_service", "id": new_id("adv"), "service": service, "type": SET_BOOL})
    return server, caller, service


async def args_object(context: CaseContext) -> Verdict:
    server, caller, service = await _serving(context, "set_bool")
    values = {"success": True, "message": "served"}
    request, response = await call_served(
        server, caller, {"op": "call_service", "service": service, "args": {"data": True}}, values, 20
    )
    if request.get("args", {}).get("data") is not True:
        return Verdict(Outcome.FAILED, f"the serving client got args {request.get('args')}")
    if response.get("result") is not True or response.get("values") != values:
        return Verdict(Outcome.FAILED, f"the caller got {response}")
    return Verdict(Outcome.OK, f"served request {request.get('args')}; the caller got {values} with its id")


async def args_list(context: CaseContext) -> Verdict:
    server, caller, service = await _serving(context, "set_bool_list")
    values = {"success": True, "message": "listed"}
    try:
        request, response = await call_served(
            server, caller, {"op": "call_service", "service": service, "args": [True]}, values, 12
        )
    except NotAnswered as missing:
        return Verdict(Outcome.NON_STRICT, f"args as a list were not carried ({missing})")
    if request.get("args", {}).get("data") is not True:
        return Verdict(Outcome.NON_STRICT, f"args [true] reached the serving client as {request.get('args')}")
    if response.get("values") != values:
        return Verdict(Outcome.FAILED, f"the caller got {response}")
    return Verdict(Outcome.OK, "args [true] reached the serving client as {data: true}")


async def no_such_service(context: CaseContext) -> Verdict:
    caller = await context.connect()
    call_id = new_id("missing")
    response = await caller.request(
        {"op": "call_service", "id": call_id, "service": context.name("nobody_serves_this"), "timeout": 2.0},
        op_is("service_response", id=call_id),
        15,
        "service_response to a call of a service nobody serves",
    )
    if response.get("result") is not False:
        return Verdict(Outcome.FAILED, f"answered {response}")
    return Verdict(Outcome.OK, f"result false, values {response.get('values')!r}")


async def call_timeout(context: CaseContext) -> Verdict:
    server, caller, service = await _serving(context, "silent")
    # The serving client sees the call and never answers.
    started = time.monotonic()
    for _ in range(20):
        call_id = new_id("slow")
        await caller.send({"op": "call_service", "id": call_id, "service": service, "args": {}, "timeout": 1.5})
        seen = await server.poll(op_is("call_service", service=service), 1.0)
        if seen is not None:
            break
        await caller.expect(op_is("service_response", id=call_id), 10, "answer to an undiscovered call")
    else:
        return Verdict(Outcome.FAILED, "the serving client never received the call")
    started = time.monotonic()
    response = await caller.expect(op_is("service_response", id=call_id), 20, "service_response after the timeout")
    waited = time.monotonic() - started
    if response.get("result") is not False:
        return Verdict(Outcome.FAILED, f"answered {response} though the serving client never answered")
    if waited > 4.5 + caller.latency:
        return Verdict(Outcome.NON_STRICT, f"result false after {waited:.1f} s (timeout 1.5 s ignored)")
    return Verdict(Outcome.OK, f"result false about {waited:.1f} s after the call reached the serving client")


async def served_failure(context: CaseContext) -> Verdict:
    server, caller, service = await _serving(context, "failing")
    request = {"op": "call_service", "service": service, "args": {"data": False}, "timeout": 2.0}
    _, response = await call_served(server, caller, request, {"success": False, "message": "no"}, 20, result=False)
    if response.get("result") is not False:
        return Verdict(Outcome.FAILED, f"the serving client answered result:false; the caller got {response}")
    return Verdict(Outcome.OK, f"the caller got result false ({response.get('values')!r})")


async def unadvertise_service(context: CaseContext) -> Verdict:
    server, caller, service = await _serving(context, "withdrawn")
    await call_served(server, caller, {"op": "call_service", "service": service, "args": {}}, {"success": True}, 20)
    await server.send({"op": "unadvertise_service", "id": new_id("unadv"), "service": service})
    await context.window(0.3)  # the server tears the ROS service down asynchronously
    call_id = new_id("after")
    await caller.send({"op": "call_service", "id": call_id, "service": service, "args": {}, "timeout": 2.0})
    reached = await server.poll(op_is("call_service", service=service), 2.5)
    response = await caller.expect(op_is("service_response", id=call_id), 15, "answer after unadvertise_service")
    if reached is not None or response.get("result") is not False:
        return Verdict(Outcome.FAILED, f"still served after unadvertise_service: {response}")
    return Verdict(Outcome.OK, "a call after unadvertise_service is answered with result false")


# --- actions -----------------------------------------------------------------------------------


async def _goal_reached(
    context: CaseContext, feedback: bool
) -> tuple[Conversation, Conversation, str, str, dict[str, Any]]:
    """A client serving the action, a client that sent it a goal, and the goal as the server saw it."""
    server, client = await context.connect_pair("server", "client")
    action = context.name("follow")
    await server.send({"op": "advertise_action", "id": new_id("adv"), "action": action, "type": ACTION_TYPE})
    for _ in range(30):  # a goal may fail while the server has not discovered the action yet
        goal_id = new_id("goal")
        await client.send(
            {
                "op": "send_action_goal",
                "id": goal_id,
                "action": action,
                "action_type": ACTION_TYPE,
                "args": GOAL,
                "feedback": feedback,
            }
        )
        goal = await server.poll(op_is("send_action_goal", action=action), 1.0)
        if goal is not None:
            return server, client, action, goal_id, goal
        early = await client.poll(op_is("action_result", id=goal_id), 1.0)
        if early is None:
            continue
        if early.get("result") is not False:
            return server, client, action, goal_id, {}
    raise NotAnswered(f"the serving client never received the goal for {action}")


async def goal_succeeds(context: CaseContext) -> Verdict:
    server, client, action, goal_id, goal = await _goal_reached(context, feedback=True)
    if not goal:
        return Verdict(Outcome.FAILED, "the goal was answered without reaching the serving client")
    await server.send({"op": "action_feedback", "id": goal.get("id"), "action": action, "values": FEEDBACK})
    feedback = await client.maybe(op_is("action_feedback", id=goal_id), 5)
    values = {"error_code": 0, "error_string": "done"}
    await server.send(
        {"op": "action_result", "id": goal.get("id"), "action": action, "values": values, "status": 4, "result": True}
    )
    result = await client.expect(op_is("action_result", id=goal_id), 15, "action_result of the goal")
    if result.get("status") != 4 or result.get("result") is not True or result.get("values") != values:
        return Verdict(Outcome.FAILED, f"the client got {result}")
    if feedback is None:
        return Verdict(Outcome.NON_STRICT, "result status 4 delivered; the feedback was not")
    return Verdict(Outcome.OK, "the goal reached the serving client; feedback and result (status 4) came back")


async def goal_canceled(context: CaseContext) -> Verdict:
    server, client, action, goal_id, goal = await _goal_reached(context, feedback=True)
    if not goal:
        return Verdict(Outcome.FAILED, "the goal was answered without reaching the serving client")
    # A goal in progress: its feedback reached the sender, so the goal was accepted.
    await server.send({"op": "action_feedback", "id": goal.get("id"), "action": action, "values": FEEDBACK})
    await client.maybe(op_is("action_feedback", id=goal_id), 5)
    await client.send({"op": "cancel_action_goal", "id": goal_id, "action": action})
    cancel = await server.expect(op_is("cancel_action_goal", action=action), 10, "cancel_action_goal to the server")
    await server.send(
        {"op": "action_result", "id": cancel.get("id"), "action": action, "values": {}, "status": 5, "result": False}
    )
    result = await client.expect(op_is("action_result", id=goal_id), 15, "action_result of the canceled goal")
    if result.get("status") != 5:
        return Verdict(Outcome.FAILED, f"the canceled goal ended with {result}")
    return Verdict(Outcome.OK, "the cancel reached the serving client; the result has status 5")


async def no_such_action(context: CaseContext) -> Verdict:
    client = await context.connect()
    goal_id = new_id("nobody")
    result = await client.request(
        {
            "op": "send_action_goal",
            "id": goal_id,
            "action": context.name("nobody_serves_this"),
            "action_type": ACTION_TYPE,
            "args": GOAL,
        },
        op_is("action_result", id=goal_id),
        25,
        "action_result for an action nobody serves",
    )
    if result.get("result") is not False:
        return Verdict(Outcome.FAILED, f"answered {result}")
    return Verdict(Outcome.OK, f"result false, status {result.get('status')}, values {result.get('values')!r}")


def _service(number: str, title: str, statements: tuple[str, ...], expected: str, run: Any) -> Case:
    return Case(number, title, "services", statements, expected, 40, run)


def _action(number: str, title: str, statements: tuple[str, ...], expected: str, run: Any) -> Case:
    return Case(number, title, "actions", statements, expected, 45, run)


CASES = (
    _service(
        "services.1",
        "client-served service, args as object",
        ("P-SRV-1", "P-SRV-2", "P-ASRV-1", "P-ASRV-2", "P-GEN-2"),
        "the serving client gets the call; the caller gets its values, result true and its id",
        args_object,
    ),
    _service("services.2", "args as a list", ("P-SRV-3",), "args [true] reach the service as {data: true}", args_list),
    _service(
        "services.3",
        "a service nobody serves",
        ("P-SRV-5",),
        "answered with result false and a reason",
        no_such_service,
    ),
    _service(
        "services.4",
        "call timeout",
        ("P-SRV-4", "P-SRV-5"),
        "a call with timeout 1.5 s the serving client never answers: result false after about 1.5 s",
        call_timeout,
    ),
    _service(
        "services.5",
        "the serving client fails",
        ("P-SRV-5", "P-ASRV-2"),
        "the serving client answers result false; the caller gets result false",
        served_failure,
    ),
    _service(
        "services.6",
        "unadvertise_service",
        ("P-ASRV-3", "P-SRV-5"),
        "a call after unadvertise_service is answered with result false",
        unadvertise_service,
    ),
    _action(
        "actions.1",
        "client-served action: goal, feedback, result",
        ("P-ACT-1", "P-ACT-2", "P-AACT-1", "P-AACT-2"),
        "the goal reaches the serving client; its feedback and result (status 4) reach the sender",
        goal_succeeds,
    ),
    _action(
        "actions.2",
        "cancel a client-served goal",
        ("P-ACT-3", "P-AACT-3"),
        "the cancel reaches the serving client; the final result has status 5",
        goal_canceled,
    ),
    _action(
        "actions.3",
        "an action nobody serves",
        ("P-ACT-4",),
        "answered with an action_result with result false",
        no_such_action,
    ),
)
