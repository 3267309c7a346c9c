"""The planner's collision world: built from the scene file, self and world collisions, attachments."""

from __future__ import annotations

import numpy as np

from at_ros.planning_scene import PlanningScene
from support.planning_scenes import UR10_START


def test_scene_file_bodies_and_filters_are_obstacles(iva_scene: PlanningScene) -> None:
    assert {"table", "rack", "cabinet", "module"} <= set(iva_scene.obstacles)
    assert {"filter/CDRA-F-0007", "filter/CDRA-F-0012", "filter/CDRA-F-0013"} == iva_scene.graspable
    assert iva_scene.collision(UR10_START) is None


def test_arm_through_the_table_is_a_collision(iva_scene: PlanningScene) -> None:
    # Upper arm forward, elbow folded down: the forearm goes through the table top.
    q = np.array([0.0, -0.6, 2.4, -1.57, -1.57, 0.0])
    assert "table" in (iva_scene.collision(q) or "")


def test_folded_arm_collides_with_itself(iva_scene: PlanningScene) -> None:
    q = np.array([0.0, -1.5708, 3.1, 0.0, 0.0, 0.0])  # elbow folded back onto the upper arm
    why = iva_scene.collision(q)
    assert why is not None
    a, b = why.split(" with ")
    assert a.endswith("_link") and b.endswith("_link")  # two links of the arm, no obstacle


def test_attached_object_moves_with_the_tool_and_is_checked(iva_scene: PlanningScene) -> None:
    name = "filter/CDRA-F-0012"
    original = iva_scene.obstacle_pose(name)
    tool = iva_scene.forward(UR10_START)
    iva_scene.set_obstacle_pose(name, tool @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.2], [0, 0, 0, 1.0]]))
    try:
        iva_scene.attach(name)
        assert iva_scene.collision(UR10_START) is None
        q = UR10_START.copy()
        q[0] = 0.6  # swing: the carried filter must come along
        iva_scene.set_joints(q)
        moved = iva_scene.obstacle_pose(name)
        np.testing.assert_allclose(
            moved[:3, 3], (iva_scene.tool_pose() @ iva_scene.attachment.tool_T_object)[:3, 3], atol=1e-6
        )
        # Lowering the tool puts the carried filter into the table: a collision of the filter, not the arm.
        low = UR10_START.copy()
        low[1] = -0.9
        why = iva_scene.collision(low)
        assert why is not None
    finally:
        iva_scene.detach()
        iva_scene.set_obstacle_pose(name, original)
