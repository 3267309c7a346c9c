"""The AT server on the IVA robot, end to end: simulation, planner and server as real processes.

Drives the services in the order a procedure does: add the CDRA filter template, register it on
the dirty filter in the cabinet, plan, unlock, execute (the filter ends up in the gripper, out
of the cabinet), register it on the empty rack slot, plan, execute (the filter is seated there).
"""

from __future__ import annotations

import math
import re
import threading
from collections.abc import Iterator

import pytest
from affordance_template_msgs.msg import ServerStatus
from at_client import AtClient
from geometry_msgs.msg import Pose

from at_ros.api import SERVICES
from support.at_server import start_stack

pytestmark = [pytest.mark.ros, pytest.mark.slow]

DIRTY = "CDRA-F-0007"
BURST = 64
EMPTY_SLOT = "rack/slot_3"


@pytest.fixture(scope="module")
def at(ros_env: dict[str, str]) -> Iterator[AtClient]:
    # Real time: executions last seconds, so "while executing" can be observed without races.
    yield from start_stack(ros_env, "iva", 1.0)


def _distance(a: Pose, b: Pose) -> float:
    return math.dist((a.position.x, a.position.y, a.position.z), (b.position.x, b.position.y, b.position.z))


def test_library_robots_and_status_are_served(at: AtClient) -> None:
    templates = at.call("get_templates")
    assert templates.success
    by_type = {t.type: t for t in templates.templates}
    assert {"cdra_filter", "ready_pose", "inspection"} <= set(by_type)
    assert "grasp_and_pull" in [t.name for t in by_type["cdra_filter"].trajectory_info]
    robots = at.call("get_robots")
    assert {r.name for r in robots.robots} == {"ur10", "eva_arm"}
    status = at.call("get_status")
    assert status.ready and status.status.affordance_template_server_active and status.status.planner_node_active
    assert at.status.robot_name == "ur10"


def test_instance_ids_are_the_lowest_free(at: AtClient) -> None:
    first = at.call("add_template", class_type="ready_pose")
    second = at.call("add_template", class_type="ready_pose")
    assert (first.instance, second.instance) == (f"ready_pose:{first.id}", f"ready_pose:{first.id + 1}")
    assert at.call("delete_template", class_type="ready_pose", id=first.id).success
    again = at.call("add_template", class_type="ready_pose")
    assert again.id == first.id
    assert {again.instance, second.instance} <= set(at.call("get_running").templates)
    for instance_id in (again.id, second.id):
        assert at.call("delete_template", class_type="ready_pose", id=instance_id).success
    at.wait_for(
        lambda: not any(t.startswith("ready_pose:") for t in at.status.running_templates),
        10,
        "status without ready_pose",
    )


def test_bad_requests_say_what_to_fix(at: AtClient) -> None:
    instance = at.call("add_template", class_type="cdra_filter")
    i = instance.id
    try:
        cases = [
            (at.call("add_template", class_type="cdra_filtre"), "unknown template 'cdra_filtre'"),
            (
                at.call("plan_command", type="cdra_filter", id=99, trajectory_name="grasp_and_pull"),
                "no running instance 'cdra_filter:99'",
            ),
            (at.call("plan_command", type="cdra_filter", id=i, trajectory_name="dance"), "no trajectory 'dance'"),
            (
                at.call(
                    "plan_command",
                    type="cdra_filter",
                    id=i,
                    trajectory_name="grasp_and_pull",
                    end_effectors=["left_hand"],
                ),
                "unknown end effector 'left_hand'",
            ),
            (at.register("cdra_filter", i, "cdra_filter", "filter/CDRA-F-9999"), "unknown frame 'filter/CDRA-F-9999'"),
            (at.register("cdra_filter", i, "lid", "world"), "no display object 'lid'"),
            (
                at.call("execute_command", type="cdra_filter", id=i, trajectory_name="grasp_and_pull"),
                "call plan_command first",
            ),
            (at.call("get_template_status", name="cdra_filter"), "must be 'Type:id'"),
        ]
        for response, expected in cases:
            assert not response.success
            assert expected in response.message, response.message
        # A registration the arm cannot take: planning says which waypoint, where the template
        # states it, the pose in the robot's base frame and why, across the planner's process.
        far = at.register("cdra_filter", i, "cdra_filter", "world")  # the world origin is in the floor
        assert far.success
        plan = at.call("plan_command", type="cdra_filter", id=i, trajectory_name="grasp_and_pull")
        assert not plan.success
        assert re.search(
            rf"waypoint 0\.0:cdra_filter:{i} \(\S*/cdra_filter\.json:\d+\): the pose x=-?\d+\.\d{{3}} .* deg "
            r"in base_link is reachable only in collision \(\S+ with module\)$",
            plan.message,
        ), plan.message
        at.wait_for(
            lambda: at.status.plan_status == ServerStatus.PLAN_FAILED and "grasp_and_pull" in at.status.last_error,
            10,
            "PLAN_FAILED status",
        )
    finally:
        at.call("delete_template", class_type="cdra_filter", id=i)


def test_hidden_waypoints_plan_the_same_motion(at: AtClient) -> None:
    shown = at.call("add_template", class_type="cdra_filter", hide_waypoints=False)
    hidden = at.call("add_template", class_type="cdra_filter", hide_waypoints=True)
    try:
        for response in (shown, hidden):
            assert at.register("cdra_filter", response.id, "cdra_filter", f"filter/{DIRTY}").success
        statuses = [
            at.call(
                "get_template_status", name=r.instance, trajectory_name="grasp_and_pull", frame_id="world"
            ).affordance_template_status[0]
            for r in (shown, hidden)
        ]
        assert statuses[0].waypoint_info[0].compact_view == [False] * 4
        assert statuses[1].waypoint_info[0].compact_view == [True] * 4
        assert [p.pose for p in statuses[0].waypoint_info[0].waypoint_poses] == [
            p.pose for p in statuses[1].waypoint_info[0].waypoint_poses
        ]
        plans = [
            at.call("plan_command", type="cdra_filter", id=r.id, trajectory_name="grasp_and_pull")
            for r in (shown, hidden)
        ]
        assert all(p.success for p in plans), [p.message for p in plans]
    finally:
        for response in (shown, hidden):
            at.call("delete_template", class_type="cdra_filter", id=response.id)


def test_steps_direct_and_backwards_choose_waypoints_as_the_original(at: AtClient) -> None:
    added = at.call("add_template", class_type="cdra_filter")
    try:
        assert at.register("cdra_filter", added.id, "cdra_filter", f"filter/{DIRTY}").success
        start = at.call(
            "plan_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull", steps=[1], direct=True
        )
        assert start.success and "waypoints [0]" in start.message, start.message
        assert start.affordance_template_status.waypoint_info[0].waypoint_plan_index == 0
        two = at.call("plan_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull", steps=[2])
        assert two.success and "waypoints [0, 1]" in two.message, two.message
        back = at.call(
            "plan_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull", steps=[1], backwards=True
        )
        assert (
            "waypoints [3]" in back.message or "0.3:cdra_filter" in back.message
        )  # not started: the last waypoint first
        bad = at.call(
            "plan_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull", steps=[9], direct=True
        )
        assert not bad.success and "between 1 and 4" in bad.message
    finally:
        at.call("delete_template", class_type="cdra_filter", id=added.id)


def test_set_waypoint_pose_moves_one_waypoint(at: AtClient) -> None:
    added = at.call("add_template", class_type="cdra_filter")
    try:
        assert at.register("cdra_filter", added.id, "cdra_filter", f"filter/{DIRTY}").success
        from geometry_msgs.msg import PoseStamped

        pose = PoseStamped()
        pose.header.frame_id = ""  # relative to the waypoint's display object
        pose.pose.position.x = -0.40
        pose.pose.orientation.w = 1.0
        moved = at.call(
            "set_waypoint_pose",
            type="cdra_filter",
            id=added.id,
            trajectory_name="grasp_and_pull",
            waypoint_id=0,
            end_effector="gripper",
            pose=pose,
        )
        assert moved.success, moved.message
        status = at.call(
            "get_template_status", name=added.instance, trajectory_name="grasp_and_pull", frame_id=f"filter/{DIRTY}"
        )
        poses = status.affordance_template_status[0].waypoint_info[0].waypoint_poses
        assert poses[0].pose.position.x == pytest.approx(-0.40, abs=1e-6)
        assert poses[1].pose.position.x == pytest.approx(-0.13, abs=1e-6)  # the others stay
        bad = at.call(
            "set_waypoint_pose",
            type="cdra_filter",
            id=added.id,
            trajectory_name="grasp_and_pull",
            waypoint_id=7,
            end_effector="gripper",
            pose=pose,
        )
        assert not bad.success and "waypoints 0..3" in bad.message
    finally:
        at.call("delete_template", class_type="cdra_filter", id=added.id)


def test_remove_dirty_filter_and_place_it_on_the_empty_rack_slot(at: AtClient) -> None:
    filt = at.call("add_template", class_type="cdra_filter")
    rival = at.call("add_template", class_type="cdra_filter")
    i = filt.id
    try:
        assert at.register("cdra_filter", i, "cdra_filter", f"filter/{DIRTY}").success
        plan = at.call("plan_command", type="cdra_filter", id=i, trajectory_name="grasp_and_pull")
        assert plan.success, plan.message
        assert plan.affordance_template_status.plan_valid
        at.wait_for(
            lambda: at.status.plan_valid and at.status.plan_status == ServerStatus.PLAN_PLANNED, 10, "plan_valid status"
        )
        # Another instance planned on the same filter and start state, to be executed too late.
        assert at.register("cdra_filter", rival.id, "cdra_filter", f"filter/{DIRTY}").success
        assert at.call("plan_command", type="cdra_filter", id=rival.id, trajectory_name="grasp_and_pull").success

        assert at.unlock_filter().success
        # Re-planning is not needed: unlocking moved neither the robot nor the filter.
        executed = at.call("execute_command", type="cdra_filter", id=i, trajectory_name="grasp_and_pull")
        assert executed.success, executed.message
        at.wait_for(
            lambda: at.held_object == DIRTY and at.cdra_present is False, 10, "filter held and out of the cabinet"
        )
        frames = at.fresh_frames()
        assert _distance(frames[f"filter/{DIRTY}"], frames["cabinet/slot"]) > 0.25
        assert _distance(frames[f"filter/{DIRTY}"], frames["tool0"]) < 0.2
        assert at.status.execute_status == ServerStatus.EXECUTE_SUCCEEDED

        stale = at.call("execute_command", type="cdra_filter", id=rival.id, trajectory_name="grasp_and_pull")
        assert not stale.success and "no longer valid" in stale.message, stale.message
        again = at.call("execute_command", type="cdra_filter", id=i, trajectory_name="grasp_and_pull")
        assert not again.success and "call plan_command first" in again.message  # a plan runs once

        assert at.register("cdra_filter", i, "cdra_filter", EMPTY_SLOT).success
        plan = at.call("plan_command", type="cdra_filter", id=i, trajectory_name="insert_and_release")
        assert plan.success, plan.message
        executed = at.call("execute_command", type="cdra_filter", id=i, trajectory_name="insert_and_release")
        assert executed.success, executed.message
        at.wait_for(lambda: at.held_object == "", 10, "gripper empty")
        frames = at.fresh_frames()
        assert _distance(frames[f"filter/{DIRTY}"], frames[EMPTY_SLOT]) < 0.01  # seated in the slot
        status = at.call("get_template_status", name=filt.instance, trajectory_name="insert_and_release")
        info = status.affordance_template_status[0].waypoint_info[0]
        assert info.waypoint_index == 3 and info.execution_valid
    finally:
        for response in (filt, rival):
            at.call("delete_template", class_type="cdra_filter", id=response.id)


def test_second_robot_command_while_executing_is_refused(at: AtClient) -> None:
    ready = at.call("add_template", class_type="ready_pose")
    other = at.call("add_template", class_type="ready_pose")
    try:
        for response in (ready, other):
            assert at.register("ready_pose", response.id, "robot_base", "robot_base").success
        assert at.call("plan_command", type="ready_pose", id=ready.id, trajectory_name="ready").success
        results = {}
        worker = threading.Thread(
            target=lambda: results.update(
                first=at.call("execute_command", type="ready_pose", id=ready.id, trajectory_name="ready")
            )
        )
        worker.start()
        at.wait_for(lambda: at.status.execute_status == ServerStatus.EXECUTE_EXECUTING, 30, "EXECUTING status")
        count = at.status_count
        second = at.call("plan_command", type="ready_pose", id=other.id, trajectory_name="ready", execute=True)
        assert not second.success and "executing ready_pose:" in second.message
        refused = at.call("execute_command", type="ready_pose", id=other.id, trajectory_name="ready")
        assert not refused.success and ("not queued" in refused.message or "call plan_command first" in refused.message)
        busy = at.call("get_status")
        assert not busy.ready  # other services answer during the execution
        at.wait_for(lambda: at.status_count >= count + 2, 10, "status published while executing")
        worker.join(120)
        assert results["first"].success, results["first"].message
        at.wait_for(
            lambda: at.status.execute_status == ServerStatus.EXECUTE_SUCCEEDED and not at.status.robot_active,
            30,
            "robot at rest",
        )
    finally:
        for response in (ready, other):
            at.call("delete_template", class_type="ready_pose", id=response.id)


def test_a_burst_of_requests_is_answered_in_full(at: AtClient) -> None:
    """Many clients polling at once (web views, tools): none of their requests may be dropped."""
    client = at.clients["get_status"]
    futures = [client.call_async(SERVICES["get_status"].Request()) for _ in range(BURST)]
    answered = threading.Semaphore(0)
    for future in futures:
        future.add_done_callback(lambda _: answered.release())
    for _ in futures:
        assert answered.acquire(timeout=30), f"only {sum(f.done() for f in futures)} of {BURST} requests were answered"
    assert all(f.result().success for f in futures)
