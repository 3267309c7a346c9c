"""Waypoint sequences on the IVA planning scene: chained plans, grasp attachment, failures named."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from at_ros.ik import IkFailure, IkSolver
from at_ros.instance import Registration, TemplateInstance
from at_ros.library import Template, load_template
from at_ros.motion_planner import Goal, MotionPlanner, WaypointPlanningError
from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import RobotConfig
from at_ros.transforms import angle_between, from_xyz_rpy, invert
from sim.scene import load_scene
from support.planning_scenes import BENCH_ARM, UR10_START

CABINET_SLOT = from_xyz_rpy([0.15, 0.90, 1.05], [0.0, 0.0, np.pi / 2])


@pytest.fixture(scope="module")
def planner(iva_scene: PlanningScene, ur10_config: RobotConfig) -> MotionPlanner:
    return MotionPlanner(iva_scene, ur10_config.planner)


def _goals(library: dict[str, Template], ur10_config: RobotConfig, trajectory: str, frame: np.ndarray) -> list[Goal]:
    return _template_goals(library["cdra_filter"], ur10_config, trajectory, "cdra_filter", frame)


def _template_goals(
    template: Template, config: RobotConfig, trajectory: str, registered: str, frame: np.ndarray
) -> list[Goal]:
    """The goals the AT server would send for ``trajectory`` with ``registered`` at ``frame``."""
    instance = TemplateInstance(template, 0, config, root_pose=np.eye(4))
    instance.register(registered, Registration("world", np.eye(4), frame))
    t = instance.trajectory(trajectory)
    return [
        Goal(
            w.label,
            w.tool_goal,
            w.waypoint.planner_type,
            w.end_effector_pose,
            gripper_action=w.gripper_action,
            object_name=w.object_name,
            object_pose=w.object_pose,
            source=w.source,
        )
        for w in instance.resolve(t, instance.end_effector(t, []))
    ]


def test_grasp_and_pull_reaches_every_waypoint_within_limits(
    planner: MotionPlanner, iva_scene: PlanningScene, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    goals = _goals(library, ur10_config, "grasp_and_pull", CABINET_SLOT)
    planned = planner.plan(UR10_START, goals)
    assert [p.label for p in planned] == [g.label for g in goals]
    assert [p.end_effector_pose for p in planned] == ["open", "open", "closed", "closed"]
    np.testing.assert_allclose(planned[0].path.positions[0], UR10_START, atol=1e-9)
    for before, after in zip(planned, planned[1:], strict=False):  # chained: each starts where the last ended
        np.testing.assert_allclose(after.path.positions[0], before.path.positions[-1], atol=1e-9)
    for p, goal in zip(planned, goals, strict=False):
        reached = iva_scene.forward(p.path.positions[-1])
        assert np.linalg.norm(reached[:3, 3] - goal.pose[:3, 3]) < 1e-3 and angle_between(reached, goal.pose) < 1e-2
        assert np.all(
            np.abs(p.path.velocities) <= iva_scene.limits.velocity * ur10_config.planner.velocity_scaling + 1e-6
        )
        for q in p.path.positions:
            assert iva_scene.within_limits(q)
    assert iva_scene.attachment is None  # the plan's grasp is not left behind in the scene


def test_pull_segment_carries_the_grasped_filter(
    planner: MotionPlanner, iva_scene: PlanningScene, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    goals = _goals(library, ur10_config, "grasp_and_pull", CABINET_SLOT)
    # Pull straight through the cabinet's back plate instead of out of the slot: the carried
    # filter (not the arm) runs into the cabinet and the wall behind it: the grasp attached it.
    assert goals[2].gripper_action == "grasp"  # stated by the template, not guessed from "closed"
    pushed = goals[:3] + [
        Goal(goals[3].label, goals[2].pose @ from_xyz_rpy([0, 0, 0.15], [0, 0, 0]), "CARTESIAN", "closed")
    ]
    with pytest.raises(
        WaypointPlanningError,
        match=r"waypoint 0\.3:cdra_filter:0: the Cartesian line to the pose .* "
        r"is blocked at \d+% by a collision \(filter/CDRA-F-0007 with (cabinet|module)\)",
    ):
        planner.plan(UR10_START, pushed)


def test_an_arm_configuration_that_fails_after_the_grasp_leaves_the_next_one_a_clean_world(
    iva_scene: PlanningScene, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    """A cabinet pose found by bench/planning.py: with the nearest arm configuration the pull
    folds the arm into itself at its end, after the filter was grasped and carried. The next
    configuration must start with the filter back in its slot, not where that pull left it."""
    slot_T_moved = from_xyz_rpy([-0.0282, 0.0073, -0.0405], [-0.0789, 0.0075, -0.0673])  # noqa: N806 (a_T_b notation)
    move = CABINET_SLOT @ slot_T_moved @ invert(CABINET_SLOT)
    saved = iva_scene.snapshot()
    cabinet, filter_ = iva_scene.obstacle_pose("cabinet"), iva_scene.obstacle_pose("filter/CDRA-F-0007")
    iva_scene.set_obstacle_pose("cabinet", move @ cabinet)
    iva_scene.set_obstacle_pose("filter/CDRA-F-0007", move @ filter_)
    try:
        goals = _goals(library, ur10_config, "grasp_and_pull", CABINET_SLOT @ slot_T_moved)
        planned = MotionPlanner(iva_scene, ur10_config.planner).plan(UR10_START, goals)
        assert [p.end_effector_pose for p in planned] == ["open", "open", "closed", "closed"]
        np.testing.assert_allclose(iva_scene.obstacle_pose("filter/CDRA-F-0007"), move @ filter_, atol=1e-6)
    finally:
        iva_scene.set_obstacle_pose("cabinet", cabinet)
        iva_scene.restore(saved)


def _first_waypoint_line(template: Template, trajectory: str) -> int:
    """The line of the first waypoint of ``trajectory`` in the template file, found in its text."""
    text = Path(template.filename).read_text()
    waypoints = text.index('"end_effector_waypoint"', text.index(f'"name": "{trajectory}"'))
    return text.count("\n", 0, text.index("{", waypoints)) + 1


def _pose_in_message(message: str, base_frame: str) -> np.ndarray:
    """The pose a failure message states in ``base_frame``, back as a 4x4 transform."""
    found = re.search(
        rf"the pose x=(\S+) y=(\S+) z=(\S+) m, roll/pitch/yaw=(\S+)/(\S+)/(\S+) deg in {base_frame} ", message
    )
    assert found, message
    values = [float(v) for v in found.groups()]
    return from_xyz_rpy(values[:3], [float(np.radians(v)) for v in values[3:]])


def _assert_states_the_pose(message: str, goal: Goal, scene_file: str | Path) -> None:
    """The message gives ``goal`` in the robot's base frame, as the scene file places the base
    (not the world frame), to the millimetre and the tenth of a degree."""
    base = load_scene(scene_file).robot.base
    expected = invert(from_xyz_rpy(base.xyz, base.rpy)) @ goal.pose
    stated = _pose_in_message(message, "base_link")
    assert np.max(np.abs(stated[:3, 3] - expected[:3, 3])) <= 0.0005 + 1e-9, message
    assert np.degrees(angle_between(stated, expected)) < 0.1, message


def test_an_unreachable_waypoint_names_its_template_line_its_pose_and_reach(
    planner: MotionPlanner, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    template = library["cdra_filter"]
    goals = _template_goals(
        template, ur10_config, "grasp_and_pull", "cdra_filter", from_xyz_rpy([3.0, 0, 1.0], [0, 0, 0])
    )
    with pytest.raises(WaypointPlanningError) as refused:
        planner.plan(UR10_START, goals)
    message = str(refused.value)
    where = f"{template.filename}:{_first_waypoint_line(template, 'grasp_and_pull')}"
    assert message.startswith(f"waypoint 0.0:cdra_filter:0 ({where}): the pose x="), message
    assert message.endswith(" deg in base_link is out of reach"), message  # one reason, nothing after it
    _assert_states_the_pose(message, goals[0], "iva")
    assert "\n" not in message and "seeds" not in message and "other" not in message, message


def test_a_waypoint_reachable_only_in_collision_names_the_contact(
    planner: MotionPlanner, iva_scene: PlanningScene, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    # Registered at the world origin, the filter's approach pose is in the module's floor.
    goals = _template_goals(library["cdra_filter"], ur10_config, "grasp_and_pull", "cdra_filter", np.eye(4))
    with pytest.raises(WaypointPlanningError) as refused:
        planner.plan(UR10_START, goals)
    message = str(refused.value)
    contact = re.search(r" deg in base_link is reachable only in collision \((\S+) with module\)$", message)
    assert contact and message.startswith("waypoint 0.0:cdra_filter:0 ("), message
    _assert_states_the_pose(message, goals[0], "iva")
    # Not a contradiction: within the limits the arm does reach the pose when collisions are not checked.
    reached = IkSolver(iva_scene, seeds=32).solve(goals[0].pose, UR10_START, check_collisions=False)
    assert isinstance(reached, np.ndarray), reached
    assert iva_scene.collision(reached) is not None


def test_a_waypoint_reachable_only_outside_the_joint_limits_names_the_joint(
    narrow_wrist_bench: tuple[RobotConfig, PlanningScene],
) -> None:
    # The grasp in front of shelf slot A needs the wrist pitched below its range (or rolled beyond it).
    config, scene = narrow_wrist_bench
    workbench = load_scene(BENCH_ARM / "workbench.yaml")
    slot = workbench.slots["shelf/slot_a"].pose
    template = load_template(BENCH_ARM / "templates" / "relocate_part.json")
    goals = _template_goals(template, config, "move_part", "part", from_xyz_rpy(slot.xyz, slot.rpy))
    start = np.array(workbench.robot.initial_positions)
    with pytest.raises(WaypointPlanningError) as refused:
        MotionPlanner(scene, config.planner).plan(start, goals)
    message = str(refused.value)
    where = f"{template.filename}:{_first_waypoint_line(template, 'move_part')}"
    assert message.startswith(f"waypoint 0.0:relocate_part:0 ({where}): the pose x="), message
    _assert_states_the_pose(message, goals[0], BENCH_ARM / "workbench.yaml")
    stated = re.search(r" deg in base_link is reachable only outside the joint limits \((.+)\)$", message)
    assert stated, message
    joints = re.findall(
        r"(\w+) would be (-?\d+\.\d\d) rad, beyond its (lower|upper) limit (-?\d+\.\d\d) rad", stated[1]
    )
    assert joints, message
    for joint, value, side, limit in joints:  # each joint named is beyond the limit it is said to pass
        i = config.joint_names.index(joint)
        assert float(limit) == pytest.approx(getattr(scene.limits, side)[i], abs=0.005)
        assert float(value) < float(limit) if side == "lower" else float(value) > float(limit)
    # Not a contradiction: no solution within the limits reaches it, collisions or not.
    alone = IkSolver(scene, seeds=32).solve(goals[0].pose, start, check_collisions=False)
    assert isinstance(alone, IkFailure) and alone.beyond_limits


def test_start_in_collision_is_refused(planner: MotionPlanner) -> None:
    with pytest.raises(WaypointPlanningError, match="start state is in collision"):
        planner.plan(np.array([0.0, -0.6, 2.4, -1.57, -1.57, 0.0]), [Goal("x", np.eye(4), "JOINT")])


RACK_SLOT_2 = from_xyz_rpy([0.96, 0.0, 1.05], [0.0, 0.0, 0.0])  # occupied by CDRA-F-0013
RACK_SLOT_3 = from_xyz_rpy([0.96, 0.25, 1.05], [0.0, 0.0, 0.0])  # empty


def test_a_closed_gripper_near_a_filter_grasps_nothing_unless_the_template_says_so(
    planner: MotionPlanner, iva_scene: PlanningScene, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    """A survey with the gripper closed, stopping in front of a seated filter and rising: nothing
    is grasped (the template states no grasp), so rising is not a collision of the filter with its
    rack (it was, when "closed within 25 cm" counted as a grasp: the filter rose with the tool)."""
    view = from_xyz_rpy([0.0, 0.0, 0.0], [0.0, np.pi / 2, 0.0])
    near = RACK_SLOT_2 @ from_xyz_rpy([-0.22, 0, 0], [0, 0, 0]) @ view
    away = from_xyz_rpy([0, 0, 0.06], [0, 0, 0]) @ near
    goals = [
        Goal("survey.0", RACK_SLOT_2 @ from_xyz_rpy([-0.35, 0, 0], [0, 0, 0]) @ view, "JOINT", "closed"),
        Goal("survey.1", near, "CARTESIAN", "closed"),
        Goal("survey.2", away, "CARTESIAN", "closed"),
    ]
    planned = planner.plan(UR10_START, goals)
    assert [p.label for p in planned] == ["survey.0", "survey.1", "survey.2"]
    np.testing.assert_allclose(iva_scene.obstacle_pose("filter/CDRA-F-0013")[:3, 3], RACK_SLOT_2[:3, 3], atol=1e-6)
    # Had the template said the survey grasps the filter, it would have carried it into the rack.
    grasping = [
        goals[0],
        Goal(
            "survey.1",
            near,
            "CARTESIAN",
            "closed",
            gripper_action="grasp",
            object_name="filter",
            object_pose=RACK_SLOT_2,
        ),
        goals[2],
    ]
    with pytest.raises(
        WaypointPlanningError,
        match=r"waypoint survey\.2: the Cartesian line to .* is blocked at \d+% by a collision "
        r"\(filter/CDRA-F-0013 with rack\)",
    ):
        planner.plan(UR10_START, grasping)


def test_a_stated_grasp_where_nothing_is_names_the_object(
    planner: MotionPlanner, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    with pytest.raises(
        WaypointPlanningError,
        match=r"waypoint 0\.2:cdra_filter:0 \(.*cdra_filter\.json:\d+\): grasps 'cdra_filter', but no graspable object "
        r"of the world is within 5 cm of where 'cdra_filter' is registered",
    ):
        planner.plan(UR10_START, _goals(library, ur10_config, "grasp_and_pull", RACK_SLOT_3))
