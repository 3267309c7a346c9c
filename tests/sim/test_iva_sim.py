"""The IVA simulator as a real process: trajectories, refusals, collisions, the CDRA filter swap.

Tests in this module share one simulator (module fixture); each one starts from wherever the
previous left the arm and moves from the current joint state.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest
from action_msgs.msg import GoalStatus
from arm_paths import ArmModel
from caretaker_sim_msgs.action import FollowJointTrajectory
from sim_client import SimClient

from sim.trajectory import ErrorCode

SCENE = "iva"
ARM = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
HOME = [0.0, -1.9, 1.9, -1.570796, -1.570796, 0.0]
CO2 = "/cdra/co2_partial_pressure"


@pytest.fixture(scope="module")
def model() -> ArmModel:
    m = ArmModel(SCENE)
    yield m
    m.close()


def move_to(
    client: SimClient, model: ArmModel, waypoints: list[list[float]], speed_fraction: float = 0.5
) -> FollowJointTrajectory.Result:
    start = client.joint_positions(ARM)
    return client.follow(ARM, model.timed(waypoints, start, speed_fraction))


def assert_ok(result: FollowJointTrajectory.Result) -> None:
    assert result.error_code == ErrorCode.SUCCESSFUL, f"trajectory failed ({result.error_code}): {result.error_string}"


def close_to(a: Sequence[float], b: Sequence[float], tol: float) -> bool:
    return all(abs(x - y) <= tol for x, y in zip(a, b, strict=False))


def test_valid_trajectory_reaches_its_goal_with_feedback(client: SimClient, model: ArmModel) -> None:
    start = client.joint_positions(ARM)
    middle = [start[0] + 0.3, start[1] + 0.2, start[2] - 0.2, start[3], start[4] + 0.3, start[5] + 0.5]
    goal = [start[0] + 0.5, start[1] + 0.3, start[2] - 0.3, start[3] - 0.2, start[4] + 0.4, start[5] + 0.8]
    client.feedback.clear()
    result = client.follow(ARM, [(1.5, middle), (3.0, goal)])
    assert_ok(result)
    assert "reached the goal" in result.error_string
    client.wait_joints(ARM, goal, 1e-3)
    # Feedback is published before the result, but the action client drops feedback that it
    # handles after the result: only feedback from during the motion is certain to arrive.
    client.wait_for(lambda: bool(client.feedback), "trajectory feedback")
    assert list(client.feedback[0].joint_names) == ARM
    strange = [
        (len(fb.actual), fb.time_from_start)
        for fb in client.feedback
        if not (len(fb.actual) == len(ARM) and 0.0 <= fb.time_from_start <= 3.0 + 1e-6)
    ]
    assert not strange, f"feedback (joints, time from start) outside the 3 s trajectory: {strange}"
    assert_ok(move_to(client, model, [HOME]))
    client.wait_joints(ARM, HOME, 1e-3)
    client.wait_value("/robot/moving", False)


def test_joints_may_be_named_in_any_order_and_subset(client: SimClient) -> None:
    start = client.joint_positions(ARM)
    result = client.follow(["wrist_3_joint", "shoulder_pan_joint"], [(0.5, [start[5] + 0.3, start[0] - 0.2])])
    assert_ok(result)
    expected = list(start)
    expected[5] += 0.3
    expected[0] -= 0.2
    client.wait_joints(ARM, expected, 1e-3)
    assert_ok(client.follow(ARM, [(0.5, start)]))


def test_cancel_stops_the_arm_part_way(client: SimClient) -> None:
    start = client.joint_positions(ARM)
    goal = [start[0] + 1.0] + start[1:]
    status, result = client.follow_and_cancel(ARM, [(60.0, goal)])
    assert status == GoalStatus.STATUS_CANCELED, result.error_string
    assert result.error_code == ErrorCode.HALTED  # stopped short: never SUCCESSFUL
    assert result.error_string.startswith("cancelled after ") and "stopped short of its goal" in result.error_string
    stopped = client.joint_positions(ARM)
    assert start[0] <= stopped[0] < goal[0] - 0.1, f"pan at {stopped[0]:.3f}: not stopped part way"
    client.wait_value("/robot/moving", False)
    assert_ok(client.follow(ARM, [(2.0, start)]))


def test_halt_service_stops_the_arm_at_once_and_says_so(client: SimClient) -> None:
    start = client.joint_positions(ARM)
    goal = [start[0] + 1.0] + start[1:]
    handle = client.start(ARM, [(60.0, goal)])
    client.wait_for(lambda: client.latest["/joint_states"].position[0] > start[0] + 0.01, "the arm moving")
    halted = client.halt("test halt")
    assert halted.success and halted.stopped and halted.message.startswith("halted the arm"), halted.message
    status, result = client.result(handle)
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == ErrorCode.HALTED
    assert result.error_string == "halted: test halt"
    held = client.joint_positions(ARM)
    assert start[0] < held[0] < goal[0] - 0.1, f"pan at {held[0]:.3f}: not stopped part way"
    client.wait_value("/robot/moving", False)
    for _ in range(3):  # later joint states: still there
        assert client.joint_positions(ARM) == held
    again = client.halt("twice")
    assert again.success and not again.stopped and again.message == "nothing was moving"
    assert_ok(client.follow(ARM, [(2.0, start)]))


def test_the_time_scale_is_a_parameter_that_refuses_what_cannot_pace(client: SimClient) -> None:
    """``time_scale`` may change while the simulator runs (a test slows one motion down to halt it
    mid-way); a value the pacing cannot divide by is refused with the reason, and leaves it as it was."""
    for wrong, said in ((-1.0, "-1.0"), (math.inf, "inf"), ("fast", "'fast'"), (True, "True")):
        refused = client.set_time_scale(wrong)
        assert not refused.successful and refused.reason == f"time_scale must be a number >= 0, got {said}"
    assert client.set_time_scale(2).successful  # an integer is a number
    start = client.joint_positions(ARM)
    assert_ok(client.follow(ARM, [(1.0, [start[0] + 0.1] + start[1:])]))  # paced at the new scale
    assert client.set_time_scale(0.0).successful
    assert_ok(client.follow(ARM, [(1.0, start)]))


def test_stamps_are_sim_time(client: SimClient) -> None:
    """joint_states come on the 1/60 s grid of sim time (4 physics steps of 1/240 s, 5 when
    rounding falls short), at rest once a second (sim/publish_gate.py): their stamps step by whole
    physics steps, whatever the wall clock does meanwhile."""
    stamps: list[int] = []

    def heard_four() -> bool:  # the client's own subscription: one made and destroyed here races its executor
        msg = client.latest.get("/joint_states")
        if msg is not None:
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            if not stamps or stamp != stamps[-1]:
                stamps.append(stamp)
        return len(stamps) >= 4

    client.wait_for(heard_four, "4 joint states", 30)
    steps = [(b - a) * 240 / 1e9 for a, b in zip(stamps, stamps[1:], strict=False)]
    # whole physics steps apart: 4 or 5 while anything moves, about 240 at rest (a sample the
    # client did not look at in time adds its steps); a wall-clock stamp would not be
    assert all(round(s) >= 4 and abs(s - round(s)) < 1e-3 for s in steps), steps


def test_robot_description_and_visual_world_describe_what_a_view_draws(client: SimClient) -> None:
    import xml.etree.ElementTree as ET

    urdf = ET.fromstring(client.value("/robot_description").data)
    joints = {j.get("name") for j in urdf.iter("joint")}
    world = client.value("/sim/visual_world")
    assert world.scene == "iva" and world.robot_name == "ur10" and list(world.arm_joints) == ARM
    assert set(ARM) | set(world.gripper_joints) <= joints
    assert world.tool_link in {link.get("name") for link in urdf.iter("link")}
    names = {o.name for o in world.objects}
    assert {"rack", "cabinet", "table", "filter/CDRA-F-0007", "filter/CDRA-F-0012", "cabinet/lamp"} <= names, names
    lamp = next(o for o in world.objects if o.name == "cabinet/lamp")
    assert list(lamp.shapes[0].rgba) == pytest.approx([0.85, 0.1, 0.1, 1.0])  # locked: red
    assert all(len(o.shapes) > 0 and all(sh.rgba[3] > 0 for sh in o.shapes) for o in world.objects)
    # Everything that moves has its pose on sim/frames under the same name; the base too.
    frames = client.fresh("/sim/frames")
    movable = {n for n in names if n.startswith(("filter/", "target/"))}
    assert movable <= set(frames.names)
    base = frames.poses[list(frames.names).index("robot_base")]
    assert (base.position.x, base.position.y, base.position.z) == pytest.approx(
        (world.robot_base.position.x, world.robot_base.position.y, world.robot_base.position.z)
    )


INVALID = [
    (
        "unknown joint",
        lambda h: (["shoulder_pan_joint", "elbow"], [(1.0, [0.0, 0.0])], None),
        ErrorCode.INVALID_JOINTS,
        "unknown joint 'elbow'",
    ),
    (
        "gripper joint",
        lambda h: (["gripper_left_finger_joint"], [(1.0, [0.01])], None),
        ErrorCode.INVALID_JOINTS,
        "not an arm joint",
    ),
    ("NaN", lambda h: (ARM, [(1.0, h[:2] + [math.nan] + h[3:])], None), ErrorCode.INVALID_GOAL, "non-finite"),
    (
        "outside limits",
        lambda h: (ARM, [(5.0, h[:2] + [3.5] + h[3:])], None),
        ErrorCode.INVALID_GOAL,
        "elbow_joint position 3.5000 rad is outside its limits",
    ),
    (
        "too fast",
        lambda h: (ARM, [(0.1, [h[0] + 1.0] + h[1:])], None),
        ErrorCode.INVALID_GOAL,
        "over its velocity limit",
    ),
    (
        "velocity over limit",
        lambda h: (ARM, [(2.0, [h[0] + 0.5] + h[1:])], [[5.0, 0, 0, 0, 0, 0]]),
        ErrorCode.INVALID_GOAL,
        "velocity 5.0000 rad/s exceeds its limit",
    ),
    (
        "non-increasing time",
        lambda h: (ARM, [(1.0, h), (1.0, [h[0] + 0.1] + h[1:])], None),
        ErrorCode.INVALID_GOAL,
        "time stamps must increase",
    ),
    ("no points", lambda h: (ARM, [], None), ErrorCode.INVALID_GOAL, "no points"),
    (
        "jump at t=0",
        lambda h: (ARM, [(0.0, [h[0] + 0.5] + h[1:])], None),
        ErrorCode.INVALID_GOAL,
        "away from the current position",
    ),
]


@pytest.mark.parametrize("build, code, reason", [case[1:] for case in INVALID], ids=[case[0] for case in INVALID])
def test_invalid_trajectory_is_refused_and_nothing_moves(
    client: SimClient,
    build: Callable[[list[float]], tuple[list[str], list[tuple[float, list[float]]], list[list[float]] | None]],
    code: int,
    reason: str,
) -> None:
    before = client.joint_positions(ARM)
    names, points, velocities = build(before)
    result = client.follow(names, points, velocities=velocities)
    assert result.error_code == code, result.error_string
    assert reason in result.error_string
    assert client.joint_positions(ARM) == before


def test_collision_aborts_and_says_what_collided(client: SimClient, model: ArmModel) -> None:
    # Swing the forearm down through the table top.
    into_table = [0.0, -0.3, 2.4, -1.570796, -1.570796, 0.0]
    result = move_to(client, model, [into_table])
    assert result.error_code == ErrorCode.COLLISION, result.error_string
    assert "hit table" in result.error_string
    stopped = client.joint_positions(ARM)
    assert not close_to(stopped, into_table, 1e-3), "the arm went through the table"
    assert_ok(move_to(client, model, [HOME]))


def test_self_collision_aborts_and_names_both_links(client: SimClient, model: ArmModel) -> None:
    # Fold the forearm down beside the upper arm: the wrist swings into the shoulder.
    folded = [0.0, -2.2, 3.1, -1.570796, 0.0, 0.0]
    result = move_to(client, model, [folded])
    assert result.error_code == ErrorCode.COLLISION, result.error_string
    assert result.error_string.startswith("self-collision: ur10/shoulder_link hit ur10/")
    assert_ok(move_to(client, model, [HOME]))


def test_locked_filter_stays_and_unlocked_filter_moves_from_cabinet_to_rack(client: SimClient, model: ArmModel) -> None:
    dirty = "CDRA-F-0007"
    client.wait_value("/cdra/filter_locked", True)
    client.wait_value("/cdra/installed_filter_id", dirty)
    client.wait_value("/cdra/installed_filter_condition", "dirty")
    seated_pose = client.frame(f"filter/{dirty}")
    assert close_to(seated_pose[0], client.frame("cabinet/slot")[0], 1e-4)
    # the bay's inventory names the filter in a slot and the slot of a filter, or says why not
    inventory = client.filter_in_slot("cabinet/slot")
    assert (inventory.success, inventory.filter_id, inventory.condition) == (True, dirty, "dirty"), inventory.message
    inventory = client.slot_of_filter("CDRA-F-0012")
    assert (inventory.success, inventory.slot, inventory.condition) == (True, "rack/slot_1", "clean"), inventory.message
    for refused, because in (
        (client.filter_in_slot("rack/slot_3"), "rack/slot_3 is empty"),
        (client.filter_in_slot("rack/slot_9"), "no slot 'rack/slot_9'; the bay has cabinet/slot, rack/slot_1"),
        (client.slot_of_filter("CDRA-F-9999"), "no filter 'CDRA-F-9999'; the bay has CDRA-F-0007, CDRA-F-0012"),
    ):
        assert not refused.success and refused.message.startswith(because), refused.message

    # Reach the cabinet handle: pre-grasp 15 cm out, then straight in; close on the handle.
    approach = grasp_in_slot(client, model, "cabinet/slot", dirty)
    client.wait_value("/gripper/held_object", dirty)

    # Locked: pulling stops the arm and the filter stays in place.
    pull = model.slot_line("cabinet/slot", 0.0, 0.30, approach[-1])
    result = move_to(client, model, pull[1:], 0.2)
    assert result.error_code == ErrorCode.PATH_TOLERANCE_VIOLATED, result.error_string
    assert "locked" in result.error_string
    assert close_to(client.frame(f"filter/{dirty}")[0], seated_pose[0], 1e-4)
    client.wait_value("/cdra/filter_present", True)

    # Unlocked: the same pull takes it out.
    assert client.unlock().success
    client.wait_value("/cdra/filter_locked", False)
    assert_ok(move_to(client, model, pull[1:], 0.2))
    client.wait_value("/cdra/filter_present", False)
    client.wait_value("/cdra/installed_filter_id", "")
    out_pos = client.frame(f"filter/{dirty}")[0]
    held = client.slot_of_filter(dirty)
    assert (held.success, held.message) == (False, f"{dirty} is held by the gripper")
    assert math.dist(out_pos, seated_pose[0]) > 0.25

    # Carry it to the empty rack slot 3 and slide it in; opening leaves it seated there.
    insert = model.slot_line("rack/slot_3", 0.45, 0.0, HOME)
    assert_ok(move_to(client, model, [HOME, insert[0]]))
    assert_ok(move_to(client, model, insert[1:], 0.2))
    release = client.gripper("open")
    assert release.success and release.held_object == "", release.message
    assert "seated in rack/slot_3" in release.message
    client.wait_value("/gripper/held_object", "")
    retreat = model.slot_line("rack/slot_3", 0.0, 0.15, insert[-1])
    assert_ok(move_to(client, model, retreat[1:], 0.2))
    assert close_to(client.frame(f"filter/{dirty}")[0], client.frame("rack/slot_3")[0], 1e-4)
    assert client.filter_in_slot("rack/slot_3").filter_id == dirty
    assert client.filter_in_slot("cabinet/slot").message == "cabinet/slot is empty"
    assert_ok(move_to(client, model, [HOME]))


def grasp_in_slot(client: SimClient, model: ArmModel, slot: str, filter_id: str) -> list[list[float]]:
    """Open, come to 15 cm out of ``slot``, go straight in and close on ``filter_id``: the approach line."""
    assert client.gripper("open").success
    approach = model.slot_line(slot, 0.15, 0.0, HOME)
    assert_ok(move_to(client, model, [approach[0]]))
    assert_ok(move_to(client, model, approach[1:], 0.2))
    grasp = client.gripper("closed")
    assert grasp.success and grasp.held_object == filter_id, grasp.message
    return approach


def test_the_cabin_co2_rises_with_the_cabinet_empty_and_falls_once_a_clean_filter_is_locked_in(
    client: SimClient, model: ArmModel
) -> None:
    """After the swap above the cabinet is empty: nothing removes the crew's CO2. Each sample is a
    sim second after the one before (sim/cabin_air_node.py), so two in a row say which way it goes."""
    clean = "CDRA-F-0012"
    client.wait_value("/cdra/filter_present", False)
    before = client.fresh(CO2).data
    assert client.fresh(CO2).data > before

    # Pick the clean filter from rack slot 1, as the dirty one came out of the cabinet.
    approach = grasp_in_slot(client, model, "rack/slot_1", clean)
    pull = model.slot_line("rack/slot_1", 0.0, 0.45, approach[-1])
    assert_ok(move_to(client, model, pull[1:], 0.2))

    # Into the cabinet, released there, and locked.
    insert = model.slot_line("cabinet/slot", 0.30, 0.0, HOME)
    assert_ok(move_to(client, model, [HOME, insert[0]]))
    assert_ok(move_to(client, model, insert[1:], 0.2))
    release = client.gripper("open")
    assert release.success and "seated in cabinet/slot" in release.message, release.message
    retreat = model.slot_line("cabinet/slot", 0.0, 0.15, insert[-1])
    assert_ok(move_to(client, model, retreat[1:], 0.2))
    client.wait_value("/cdra/installed_filter_id", clean)
    assert client.fresh(CO2).data > before  # still above where the cabin was when it emptied
    assert client.lock().success
    client.wait_value("/cdra/filter_locked", True)
    locked_in = client.fresh(CO2).data  # a sample that may straddle the lock
    after = client.fresh(CO2).data
    assert after < locked_in
    assert client.fresh(CO2).data < after
    assert_ok(move_to(client, model, [HOME]))


def test_the_cabin_knobs_are_parameters_that_move_what_is_published_and_refuse_what_is_out_of_range(
    client: SimClient,
) -> None:
    """``cabin_start_ppco2`` puts the cabin's CO2 there at once, ``cabin_chemistry_scale`` runs it
    faster (sim/cabin_knobs.py). The clean filter locked in above brings the cabin down: at its own
    rate by under a thousandth of a mmHg a sim second, 60 times faster by a few hundredths."""
    client.wait_value("/cdra/filter_locked", True)
    for name, wrong, said in (
        ("cabin_start_ppco2", -1.0, "cabin_start_ppco2 must be a number >= 0, got -1.0"),
        ("cabin_start_ppco2", math.nan, "cabin_start_ppco2 must be a number >= 0, got nan"),
        ("cabin_chemistry_scale", 0.0, "cabin_chemistry_scale must be a number > 0 and <= 3600, got 0.0"),
        ("cabin_chemistry_scale", "fast", "cabin_chemistry_scale must be a number > 0 and <= 3600, got 'fast'"),
    ):
        refused = client.set_parameter(name, wrong)
        assert not refused.successful and refused.reason == said
    assert 1.0 < client.fresh(CO2).data < 4.0  # as it was: where the clean filter keeps it
    assert client.set_parameter("cabin_start_ppco2", 4.5).successful
    first, second = client.fresh(CO2).data, client.fresh(CO2).data
    assert 4.49 < second < first <= 4.5
    assert client.set_parameter("cabin_chemistry_scale", 60).successful  # an integer is a number
    fast, faster = client.fresh(CO2).data, client.fresh(CO2).data
    assert fast - faster > 0.015
    assert client.set_parameter("cabin_chemistry_scale", 1.0).successful


def test_scene_camera_capture_saves_a_png(client: SimClient, capture_dir: Path) -> None:
    response = client.capture("scene", "after swap")
    assert response.success, response.message
    assert response.image.width == 640 and response.image.height == 480
    assert len(response.image.data) == 640 * 480 * 3
    assert len(set(bytes(response.image.data[::997]))) > 10, "image is (nearly) uniform"
    assert response.path.startswith(str(capture_dir)) and response.path.endswith(".png")
    assert "after_swap" in response.path
    with open(response.path, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"


def test_unknown_camera_and_gripper_pose_are_refused(client: SimClient) -> None:
    response = client.capture("nope")
    assert not response.success and "unknown camera 'nope'" in response.message
    grip = client.gripper("half")
    assert not grip.success and "unknown gripper pose 'half'" in grip.message
