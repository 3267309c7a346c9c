"""The ``at`` profile: an Affordance Template server reached through the bridge, driven as the AT
SysRep's plugin drives it (sysrep/affordance_templates.yaml): add, list, register, plan, execute,
status, halt, delete, and the errors for an unknown template and an unreachable pose.

It assumes the robot has the ``ready_pose`` template (a ``ready`` trajectory relative to the
display object ``robot_base``, registered to the frame ``robot_base``), as every robot of
Caretaker's library does; services under ``/affordance_template_server``.
"""

from __future__ import annotations

from typing import Any

from .outcome import Outcome
from .runner import Case, CaseContext, Deviation, Verdict
from .session import Conversation, op_is
from .steps import new_id

__all__ = ["CASES"]

PREFIX = "/affordance_template_server"
TEMPLATE, TRAJECTORY, OBJECT, FRAME = "ready_pose", "ready", "robot_base", "robot_base"
MOTION = 90.0  # seconds a plan or an execution may take on a loaded machine


async def call(conversation: Conversation, name: str, args: dict[str, Any], timeout: float = 20) -> dict[str, Any]:
    """Call an AT service; its values (a failed call ends the case FAILED with the reason)."""
    call_id = new_id(name)
    response = await conversation.request(
        {"op": "call_service", "id": call_id, "service": f"{PREFIX}/{name}", "args": args, "timeout": timeout},
        op_is("service_response", id=call_id),
        timeout + 10,
        f"the answer of {PREFIX}/{name}",
    )
    values = response.get("values")
    if response.get("result") is not True or not isinstance(values, dict):
        raise Deviation(Outcome.FAILED, f"{name} was not answered: {values!r}")
    return values


def _pose(frame: str, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> dict[str, Any]:
    return {
        "header": {"frame_id": frame},
        "pose": {"position": {"x": x, "y": y, "z": z}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
    }


async def _added(conversation: Conversation) -> tuple[int, str]:
    request = {"class_type": TEMPLATE, "pose": _pose(""), "hide_waypoints": True}
    values = await call(conversation, "add_template", request)
    if values.get("success") is not True:
        raise Deviation(Outcome.FAILED, f"add_template {TEMPLATE} failed: {values.get('message')!r}")
    return int(values["id"]), str(values["instance"])


async def _registered(conversation: Conversation, number: int) -> None:
    objects = [{"type": TEMPLATE, "name": OBJECT, "id": number, "stamped_pose": _pose(FRAME)}]
    values = await call(conversation, "set_object_pose", {"objects": objects})
    if values.get("success") is not True:
        raise Deviation(Outcome.FAILED, f"set_object_pose failed: {values.get('message')!r}")


async def _deleted(conversation: Conversation, number: int) -> None:
    await call(conversation, "delete_template", {"class_type": TEMPLATE, "id": number})


async def server_status(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    values = await call(conversation, "get_status", {})
    status = values.get("status", {})
    if values.get("ready") is not True or not isinstance(status, dict) or "execute_status" not in status:
        return Verdict(Outcome.FAILED, f"get_status answered {values}")
    await conversation.send({"op": "subscribe", "id": new_id("status"), "topic": f"{PREFIX}/status"})
    published = await conversation.expect(op_is("publish", topic=f"{PREFIX}/status"), 10, "a status message")
    telemetry = ("robot_active", "planner_node_active", "affordance_template_server_active", "plan_valid")
    missing = [name for name in telemetry if name not in published.get("msg", {})]
    if missing:
        return Verdict(Outcome.FAILED, f"the status topic lacks {missing}")
    return Verdict(Outcome.OK, f"ready; the status topic carries the SysRep telemetry ({status.get('robot_name')})")


async def add_list_delete(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    number, instance = await _added(conversation)
    running = await call(conversation, "get_running", {})
    if instance not in running.get("templates", []):
        return Verdict(Outcome.FAILED, f"{instance} added but get_running lists {running.get('templates')}")
    deleted = await call(conversation, "delete_template", {"class_type": TEMPLATE, "id": number})
    after = await call(conversation, "get_running", {})
    if deleted.get("success") is not True or instance in after.get("templates", []):
        return Verdict(Outcome.FAILED, f"delete of {instance}: {deleted}; still running: {after.get('templates')}")
    return Verdict(Outcome.OK, f"{instance} added, listed, deleted")


async def plan_and_execute(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    number, instance = await _added(conversation)
    try:
        await _registered(conversation, number)
        command = {"type": TEMPLATE, "id": number, "trajectory_name": TRAJECTORY, "end_effectors": []}
        plan = {**command, "steps": [], "direct": False, "backwards": False, "execute": False}
        planned = await call(conversation, "plan_command", plan, MOTION)
        status = planned.get("affordance_template_status", {})
        if planned.get("success") is not True or status.get("plan_valid") is not True:
            return Verdict(Outcome.FAILED, f"plan of {instance}: {planned.get('message')!r}")
        executed = await call(conversation, "execute_command", command, MOTION)
        if executed.get("success") is not True:
            return Verdict(Outcome.FAILED, f"execute of {instance}: {executed.get('message')!r}")
        server = (await call(conversation, "get_status", {})).get("status", {})
        if server.get("execute_status") != "SUCCEEDED":
            return Verdict(Outcome.FAILED, f"after the execution the status says {server.get('execute_status')!r}")
    finally:
        await _deleted(conversation, number)
    return Verdict(Outcome.OK, f"{instance} registered, planned, executed: execute_status SUCCEEDED")


async def halt(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    values = await call(conversation, "halt", {"reason": "interop suite: halt while idle"})
    if values.get("success") is not True:
        return Verdict(Outcome.FAILED, f"halt: {values.get('message')!r}")
    return Verdict(Outcome.OK, f"halt confirmed: {values.get('message')!r}")


async def unknown_template(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    name = "interop_no_such_template"
    values = await call(conversation, "add_template", {"class_type": name, "pose": _pose(""), "hide_waypoints": True})
    if values.get("success") is not False or not values.get("message"):
        return Verdict(Outcome.FAILED, f"add of an unknown template answered {values}")
    if name not in str(values.get("message")):
        return Verdict(Outcome.NON_STRICT, f"refused without naming the template: {values.get('message')!r}")
    return Verdict(Outcome.OK, f"refused: {values.get('message')!r}")


async def unreachable_pose(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    number, instance = await _added(conversation)
    try:
        await _registered(conversation, number)
        far = {"type": TEMPLATE, "id": number, "trajectory_name": TRAJECTORY, "waypoint_id": 0}
        moved = await call(conversation, "set_waypoint_pose", {**far, "end_effector": "", "pose": _pose(OBJECT, 9.0)})
        if moved.get("success") is not True:
            # refusing the pose itself is as good as refusing to plan to it
            return Verdict(Outcome.OK, f"a waypoint 9 m away was refused: {moved.get('message')!r}")
        plan = {
            "type": TEMPLATE, "id": number, "trajectory_name": TRAJECTORY, "end_effectors": [], "steps": [],
            "direct": False, "backwards": False, "execute": False,
        }  # fmt: skip
        planned = await call(conversation, "plan_command", plan, MOTION)
        if planned.get("success") is not False or not planned.get("message"):
            return Verdict(Outcome.FAILED, f"a plan to a waypoint 9 m away answered {planned}")
        if (await call(conversation, "get_status", {})).get("ready") is not True:
            return Verdict(Outcome.FAILED, "the server is not ready after the failed plan")
    finally:
        await _deleted(conversation, number)
    return Verdict(Outcome.OK, f"the plan was refused: {planned.get('message')!r}")


def _case(number: str, title: str, statements: tuple[str, ...], expected: str, run: Any, timeout: float) -> Case:
    return Case(number, title, "at", statements, expected, timeout, run)


CASES = (
    _case("at.1", "server status", ("P-AT-1",), "ready; a ServerStatus on the status topic", server_status, 40),
    _case("at.2", "add, list, delete", ("P-AT-2",), "the instance is listed, then gone", add_list_delete, 60),
    _case(
        "at.3",
        "register, plan, execute",
        ("P-AT-3", "P-AT-4", "P-AT-5"),
        "ready_pose registered at robot_base, planned (plan_valid) and executed (SUCCEEDED)",
        plan_and_execute,
        2 * MOTION + 60,
    ),
    _case("at.4", "halt", ("P-AT-6",), "the halt is confirmed", halt, 40),
    _case("at.5", "unknown template", ("P-AT-7",), "success false, the message names it", unknown_template, 40),
    _case(
        "at.6",
        "unreachable pose",
        ("P-AT-8",),
        "a plan to a waypoint 9 m away fails with a message; the server stays ready",
        unreachable_pose,
        MOTION + 60,
    ),
)
