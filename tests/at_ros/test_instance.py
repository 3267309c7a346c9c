"""Template instances: ids, the original's waypoint index sequence, frames, registration, staleness."""

from __future__ import annotations

import numpy as np
import pytest

from at_ros.instance import (
    ExecutionOutcome,
    InstanceError,
    PlanState,
    Registration,
    StoredPlan,
    TemplateInstance,
    next_free_id,
    path_sequence,
)
from at_ros.library import Template, default_library_path, load_library
from at_ros.robot_config import RobotConfig, load_robot_configs
from at_ros.transforms import from_xyz_rpy


@pytest.fixture(scope="module")
def library() -> dict[str, Template]:
    return load_library(default_library_path() / "templates")


@pytest.fixture(scope="module")
def ur10() -> RobotConfig:
    return load_robot_configs()["ur10"]


def test_next_free_id_is_the_lowest_unused() -> None:
    assert next_free_id(set()) == 0
    assert next_free_id({0, 1, 3}) == 2
    with pytest.raises(InstanceError, match="delete an instance"):
        next_free_id(set(range(256)))


@pytest.mark.parametrize(
    ("n", "current", "steps", "direct", "backwards", "expected"),
    [
        (4, -1, None, False, False, [0, 1, 2, 3]),  # default: the whole trajectory
        (4, 2, None, False, False, [0, 1, 2, 3]),
        (4, -1, None, False, True, [3, 2, 1, 0]),
        (4, -1, 1, True, False, [0]),  # START button
        (4, 1, 4, True, False, [3]),  # END button
        (4, 2, 0, False, False, [2]),  # CURRENT
        (4, -1, 2, False, False, [0, 1]),  # not started: the first step reaches waypoint 0
        (4, 3, 2, False, False, [0, 1]),  # wraps around
        (4, -1, 2, False, True, [3, 2]),
        (4, 0, 1, False, True, [3]),
    ],
)
def test_path_sequence_matches_the_original(
    n: int, current: int, steps: int | None, direct: bool, backwards: bool, expected: list[int]
) -> None:
    assert path_sequence(n, current, steps, direct=direct, backwards=backwards) == expected


@pytest.mark.parametrize(
    ("current", "backwards", "expected"),
    [
        (1, False, [2, 3]),  # halted after waypoint 1: the rest
        (-1, False, [0, 1, 2, 3]),  # halted before the first waypoint: all of it
        (3, False, [0, 1, 2, 3]),  # at its end: all of it again
        (1, True, [3, 2, 1, 0]),  # backwards is always whole
    ],
)
def test_an_interrupted_trajectory_resumes_after_the_last_waypoint_reached(
    current: int, backwards: bool, expected: list[int]
) -> None:
    assert path_sequence(4, current, None, direct=False, backwards=backwards, resume=True) == expected
    assert path_sequence(4, current, 2, direct=False, backwards=False, resume=True) == path_sequence(
        4, current, 2, direct=False, backwards=False
    )


def test_registering_to_another_frame_starts_over_and_records_why_the_plan_went(
    library: dict[str, Template], ur10: RobotConfig
) -> None:
    instance = TemplateInstance(library["cdra_filter"], 0, ur10, root_pose=np.eye(4))
    slot = from_xyz_rpy([0.15, 0.9, 1.05], [0, 0, np.pi / 2])
    instance.register("cdra_filter", Registration("cabinet/slot", np.eye(4), slot))
    progress = instance.progress["grasp_and_pull"]
    progress.current_index, progress.outcome = 1, ExecutionOutcome.HALTED
    plan = StoredPlan("grasp_and_pull", "gripper", [2, 3], [], {}, {}, "", plan_id="p1")
    instance.plan = instance.plans["grasp_and_pull"] = plan
    instance.register(
        "cdra_filter", Registration("cabinet/slot", from_xyz_rpy([0.005, 0, 0], [0, 0, 0]), slot)
    )  # nudged
    assert progress.interrupted and instance.plan is None
    assert plan.state == PlanState.INVALIDATED and plan.state_reason == "cdra_filter:0 registered to 'cabinet/slot'"
    assert instance.last_plan() is plan and instance.last_plan("insert_and_release") is None
    instance.register("cdra_filter", Registration("rack/slot_3", np.eye(4), slot))  # another object
    assert not progress.interrupted and progress.current_index == 1


def test_plan_states_are_the_get_plan_service_constants() -> None:
    from affordance_template_msgs.srv import GetPlan

    states = {k: v for k, v in vars(PlanState).items() if not k.startswith("_")}
    assert states == {k: getattr(GetPlan.Response, k) for k in states}


@pytest.mark.parametrize(
    ("current", "steps", "direct", "message"),
    [(-1, 0, False, "not started"), (0, 5, True, "between 1 and 4"), (0, -2, False, ">= 0")],
)
def test_path_sequence_rejects_impossible_requests(current: int, steps: int | None, direct: bool, message: str) -> None:
    with pytest.raises(InstanceError, match=message):
        path_sequence(4, current, steps, direct=direct, backwards=False)


def test_waypoint_frames_follow_registration_and_original_naming(
    library: dict[str, Template], ur10: RobotConfig
) -> None:
    instance = TemplateInstance(library["cdra_filter"], 2, ur10, root_pose=np.eye(4))
    assert instance.key == "cdra_filter:2"
    slot = from_xyz_rpy([0.15, 0.9, 1.05], [0, 0, np.pi / 2])
    instance.register("cdra_filter", Registration("cabinet/slot", np.eye(4), slot))
    trajectory = instance.trajectory("grasp_and_pull")
    resolved = instance.resolve(trajectory, instance.end_effector(trajectory, []))
    assert [w.label for w in resolved] == [f"0.{i}:cdra_filter:2" for i in range(4)]
    # Grasp waypoint: 0.13 m in front of the slot along the slot's x (world -y here), tool z into the slot.
    grasp = resolved[1].tool_goal
    np.testing.assert_allclose(grasp[:3, 3], [0.15, 0.9 - 0.13, 1.05], atol=1e-6)
    np.testing.assert_allclose(grasp[:3, 2], slot[:3, 0], atol=1e-5)
    assert [w.end_effector_pose for w in resolved] == ["open", "open", "closed", "closed"]


def test_unknown_names_say_what_exists(library: dict[str, Template], ur10: RobotConfig) -> None:
    instance = TemplateInstance(library["cdra_filter"], 0, ur10, root_pose=np.eye(4))
    with pytest.raises(InstanceError, match="no trajectory 'fly'.*grasp_and_pull"):
        instance.trajectory("fly")
    trajectory = instance.trajectory("grasp_and_pull")
    with pytest.raises(InstanceError, match="unknown end effector 'left_hand'.*gripper"):
        instance.end_effector(trajectory, ["left_hand"])
    with pytest.raises(InstanceError, match="no display object 'lid'"):
        instance.register("lid", Registration("world", np.eye(4), np.eye(4)))


def test_set_waypoint_moves_only_that_waypoint_and_drops_the_plan(
    library: dict[str, Template], ur10: RobotConfig
) -> None:
    instance = TemplateInstance(library["cdra_filter"], 0, ur10, root_pose=np.eye(4))
    trajectory = instance.trajectory("grasp_and_pull")
    ee = instance.end_effector(trajectory, [])
    before = [w.frame_pose for w in instance.resolve(trajectory, ee)]
    instance.plan = StoredPlan("grasp_and_pull", "gripper", [0], [], {}, {}, "")
    target = from_xyz_rpy([0.5, 0.1, 1.0], [0, 0, 0])
    instance.set_waypoint(trajectory, ee, 1, target)
    after = [w.frame_pose for w in instance.resolve(trajectory, ee)]
    np.testing.assert_allclose(after[1], target, atol=1e-9)
    np.testing.assert_allclose(after[0], before[0])
    assert instance.plan is None


def test_stale_reason_sees_moved_objects_robot_and_gripper(library: dict[str, Template], ur10: RobotConfig) -> None:
    instance = TemplateInstance(library["cdra_filter"], 0, ur10, root_pose=np.eye(4))
    frame = from_xyz_rpy([1, 0, 1], [0, 0, 0])
    reg = Registration("filter/A", np.eye(4), frame)
    plan = StoredPlan("grasp_and_pull", "gripper", [0], [], {"j1": 0.5}, {"cdra_filter": reg}, "")
    assert instance.stale_reason(plan, {"filter/A": frame}, {"j1": 0.5}, "", 0.02) is None
    moved = from_xyz_rpy([1.02, 0, 1], [0, 0, 0])
    assert "moved since planning" in instance.stale_reason(plan, {"filter/A": moved}, {"j1": 0.5}, "", 0.02)
    assert "robot moved" in instance.stale_reason(plan, {"filter/A": frame}, {"j1": 0.6}, "", 0.02)
    assert "holds 'filter/A'" in instance.stale_reason(plan, {"filter/A": frame}, {"j1": 0.5}, "filter/A", 0.02)
    assert "no longer published" in instance.stale_reason(plan, {}, {"j1": 0.5}, "", 0.02)
