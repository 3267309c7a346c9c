"""The planner's world follows the registrations (at_ros/registered_world.py), on the IVA scene's
collision world as the simulation publishes it: a registered slot moves its body and what is
seated in it, a filter registered by its own frame moves while it is still where it was, the held
filter never moves, and the world is as drawn again after the plan.

A unit test of the module alone; the IVA demo on displaced worlds (tests/interop/test_displaced_demos.py)
plans and moves the real arm with it, to where perception located things.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from at_ros.planning_scene import PlanningScene
from at_ros.registered_world import RegisteredFrame, located_poses, located_world
from at_ros.transforms import from_xyz_quat
from sim.scene import load_scene

DIRTY, CLEAN_1, CLEAN_2 = "filter/CDRA-F-0007", "filter/CDRA-F-0012", "filter/CDRA-F-0013"


@pytest.fixture(scope="module")
def frames() -> dict[str, np.ndarray]:
    """The slots where the scene file draws them (sim/frames on a displaced world, too)."""
    return {name: from_xyz_quat(s.pose.xyz, s.pose.quaternion) for name, s in load_scene("iva").slots.items()}


def _correction(dx: float, dy: float, dz: float, yaw_deg: float) -> np.ndarray:
    return from_xyz_quat((dx, dy, dz), p.getQuaternionFromEuler((0.0, 0.0, math.radians(yaw_deg))))


def _registered(frame: str, correction: np.ndarray, drawn: np.ndarray) -> RegisteredFrame:
    return RegisteredFrame(frame, correction @ drawn, drawn)


def _everything(scene: PlanningScene) -> dict[str, np.ndarray]:
    return {name: scene.obstacle_pose(name) for name in scene.obstacles}


def test_a_registered_slot_moves_its_body_and_the_filter_seated_in_it(
    iva_scene: PlanningScene, frames: dict[str, np.ndarray]
) -> None:
    drawn = _everything(iva_scene)
    cabinet = _correction(0.03, -0.02, 0.01, 5.0)
    moved = located_poses(iva_scene, [_registered("cabinet/slot", cabinet, frames["cabinet/slot"])], frames, None)
    assert set(moved) == {"cabinet", DIRTY}
    np.testing.assert_allclose(moved["cabinet"], cabinet @ drawn["cabinet"], atol=1e-9)
    np.testing.assert_allclose(moved[DIRTY], cabinet @ drawn[DIRTY], atol=1e-6)

    rack = _correction(-0.01, 0.04, 0.0, -7.0)
    moved = located_poses(iva_scene, [_registered("rack/slot_3", rack, frames["rack/slot_3"])], frames, None)
    # the empty slot located: the rack moves, and with it the filters seated in its other slots
    assert set(moved) == {"rack", CLEAN_1, CLEAN_2}
    for name in moved:
        np.testing.assert_allclose(moved[name], rack @ drawn[name], atol=1e-6)


def test_a_filters_own_registration_wins_and_the_held_filter_stays_with_the_gripper(
    iva_scene: PlanningScene, frames: dict[str, np.ndarray]
) -> None:
    drawn = _everything(iva_scene)
    rack, own = _correction(-0.01, 0.04, 0.0, -7.0), _correction(0.002, -0.003, 0.001, 1.0)
    registered = [
        _registered(CLEAN_1, own, drawn[CLEAN_1]),  # located by its markers first, the rack after
        _registered("rack/slot_3", rack, frames["rack/slot_3"]),
    ]
    moved = located_poses(iva_scene, registered, frames, None)
    np.testing.assert_allclose(moved[CLEAN_1], own @ drawn[CLEAN_1], atol=1e-6)
    np.testing.assert_allclose(moved[CLEAN_2], rack @ drawn[CLEAN_2], atol=1e-6)

    held = located_poses(iva_scene, registered, frames, CLEAN_1)
    assert CLEAN_1 not in held and CLEAN_2 in held


def test_a_filter_moved_since_its_registration_is_where_the_world_model_says(
    iva_scene: PlanningScene, frames: dict[str, np.ndarray]
) -> None:
    drawn = _everything(iva_scene)
    registered = [_registered(CLEAN_1, _correction(0.01, 0.0, 0.0, 2.0), drawn[CLEAN_1])]
    iva_scene.set_obstacle_pose(CLEAN_1, frames["cabinet/slot"])  # the robot has put it in the cabinet since
    try:
        assert located_poses(iva_scene, registered, frames, None) == {}
    finally:
        iva_scene.set_obstacle_pose(CLEAN_1, drawn[CLEAN_1])


def test_frames_nothing_carries_move_nothing_and_the_world_is_as_drawn_after_the_plan(
    iva_scene: PlanningScene, frames: dict[str, np.ndarray]
) -> None:
    drawn = _everything(iva_scene)
    nowhere = _correction(0.5, 0.0, 0.0, 30.0)
    assert located_poses(iva_scene, [_registered("robot_base", nowhere, np.eye(4))], frames, None) == {}

    cabinet = _correction(0.03, -0.02, 0.01, 5.0)
    with located_world(
        iva_scene, [_registered("cabinet/slot", cabinet, frames["cabinet/slot"])], frames, None
    ) as moved:
        np.testing.assert_allclose(iva_scene.obstacle_pose("cabinet"), moved["cabinet"], atol=1e-6)
    after = _everything(iva_scene)
    for name, pose in drawn.items():
        np.testing.assert_allclose(after[name], pose, atol=1e-6, err_msg=name)
