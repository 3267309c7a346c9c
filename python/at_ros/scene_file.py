"""Builds the planner's collision world from the simulation's scene file (sim/scenes/*.yaml).

The planner uses the simulation's own scene loader (``sim.scene.build_world``) on its private
pybullet client, so both worlds come from one file; poses of things that move (filters) are
then corrected from the simulation's frames. The loader's robot is replaced by one loaded with
self-collision enabled, which the planner needs and the simulation does not.
"""

from __future__ import annotations

import pybullet as p

from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import RobotConfig
from at_ros.transforms import from_xyz_quat
from sim.scene import build_world, load_scene

__all__ = ["build_planning_scene"]


def build_planning_scene(config: RobotConfig) -> PlanningScene:
    """The robot of ``config`` in the collision world of its scene file.

    Obstacles are named as the simulation's frames are (``filter/<id>``, body names), so frame
    updates find them. Inspection targets are drawn panels without collision shapes: skipped.
    """
    scene = load_scene(config.scene)
    client = p.connect(p.DIRECT)
    world = build_world(scene, client, with_filters=True, with_targets=False)
    p.removeBody(world.robot, physicsClientId=client)
    base = from_xyz_quat(scene.robot.base.xyz, scene.robot.base.quaternion)
    planning = PlanningScene(
        config.urdf, config.joint_names, config.tool_link,
        client=client, base_pose=base, gripper_links=config.planner.gripper_links,
    )
    for name, body in world.bodies.items():
        planning.add_obstacle(name, body)
    for filter_id, body in world.filters.items():
        planning.add_obstacle(f"filter/{filter_id}", body, graspable=True)
    return planning
