"""The planner's collision world, built from the ``CollisionWorld`` the robot side publishes.

The planner never reads the simulation's scene file: the world's geometry arrives on
``sim/collision_world`` (latched) from whatever owns the world — the simulation here, a world
model on a real robot — and the poses of things that move follow on ``sim/frames``. Objects keep
their names from the message (``filter/<id>``, body names), so frame updates find them.
"""

from __future__ import annotations

import pybullet as p
from caretaker_sim_msgs.msg import CollisionObject, CollisionShape, CollisionWorld

from at_ros.messages import matrix_from_pose
from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import RobotConfig
from at_ros.transforms import to_xyz_quat

__all__ = ["build_planning_scene"]


def _add_object(scene: PlanningScene, obj: CollisionObject) -> None:
    kinds, extents, radii, lengths, positions, orientations = [], [], [], [], [], []
    for shape in obj.shapes:
        if shape.type not in (CollisionShape.BOX, CollisionShape.CYLINDER):
            raise ValueError(f"object {obj.name!r}: collision shape type {shape.type!r} is not box or cylinder")
        pos, quat = to_xyz_quat(matrix_from_pose(shape.pose))
        kinds.append(p.GEOM_BOX if shape.type == CollisionShape.BOX else p.GEOM_CYLINDER)
        extents.append([float(v) / 2 for v in shape.size])
        radii.append(float(shape.radius))
        lengths.append(float(shape.length))
        positions.append(pos.tolist())
        orientations.append(quat.tolist())
    collision = p.createCollisionShapeArray(
        shapeTypes=kinds,
        halfExtents=extents,
        radii=radii,
        lengths=lengths,
        collisionFramePositions=positions,
        collisionFrameOrientations=orientations,
        physicsClientId=scene.client,
    )
    pos, quat = to_xyz_quat(matrix_from_pose(obj.pose))
    # pybullet reports no contacts between two bodies of mass 0: a graspable object that the
    # tool carries must be checked against the static ones. The planning world never steps, so
    # the mass is never felt.
    mass = 1.0 if obj.graspable else 0.0
    body = p.createMultiBody(mass, collision, -1, pos.tolist(), quat.tolist(), physicsClientId=scene.client)
    scene.add_obstacle(obj.name, body, graspable=obj.graspable, frames=list(obj.frames))


def build_planning_scene(config: RobotConfig, world: CollisionWorld) -> PlanningScene:
    """The robot of ``config`` (self-collision on) at the world's robot base, among its objects.

    Raises:
        ValueError: the world has a shape type the planner does not know, or the robot model
            lacks the config's joints or tool link.
    """
    scene = PlanningScene(
        config.urdf,
        config.joint_names,
        config.tool_link,
        base_pose=matrix_from_pose(world.robot_base),
        gripper_links=config.planner.gripper_links,
    )
    try:
        for obj in world.objects:
            _add_object(scene, obj)
    except ValueError:
        scene.close()
        raise
    return scene
