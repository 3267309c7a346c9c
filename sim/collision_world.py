"""What in a scene collides, as the ``CollisionWorld`` message the simulation latches for planners.

A planner on the robot side needs the world's geometry; reading the simulation's scene file
would tie it to this simulation, so the simulation publishes it instead (``sim/collision_world``,
transient local), as a world model on a real robot would. Inspection targets and the cabinet lamp
are drawn only and have no collision shapes, so they are not in it.
"""

from __future__ import annotations

from caretaker_sim_msgs.msg import CollisionObject, CollisionShape, CollisionWorld
from geometry_msgs.msg import Pose as PoseMsg

from sim.scene import Pose, Scene, Shape, filter_parts, slot_body

__all__ = ["collision_world", "point_pose", "pose_message", "shape_message"]


def pose_message(pose: Pose) -> PoseMsg:
    return point_pose(pose.xyz, pose.quaternion)


def point_pose(position: tuple[float, ...], orientation: tuple[float, ...]) -> PoseMsg:
    """A geometry_msgs/Pose of a position and an orientation quaternion (x, y, z, w)."""
    msg = PoseMsg()
    msg.position.x, msg.position.y, msg.position.z = (float(v) for v in position)
    msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w = (float(v) for v in orientation)
    return msg


def shape_message(shape: Shape, rgba: tuple[float, float, float, float]) -> CollisionShape:
    msg = CollisionShape()
    msg.type = shape.type
    msg.size = [float(v) for v in shape.size]
    msg.radius = float(shape.radius)
    msg.length = float(shape.length)
    msg.pose = pose_message(shape.pose)
    msg.rgba = [float(v) for v in rgba]
    return msg


def collision_world(scene: Scene) -> CollisionWorld:
    """The static bodies (with the slots fixed to them) and the filters (graspable, in their
    starting slots) of ``scene``."""
    msg = CollisionWorld()
    msg.scene = scene.name
    msg.robot_name = scene.robot.name
    msg.robot_base = pose_message(scene.robot.base)
    for body in scene.bodies:
        obj = CollisionObject()
        obj.name = body.name
        obj.pose = pose_message(body.pose)
        obj.shapes = [shape_message(s, body.color) for s in body.shapes]
        obj.frames = [slot for slot in scene.slots if slot_body(scene, slot) == body.name]
        msg.objects.append(obj)
    if scene.filter_model is not None:
        for spec in scene.filters:
            obj = CollisionObject()
            obj.name = f"filter/{spec.id}"
            obj.pose = pose_message(scene.slots[spec.slot].pose)
            obj.shapes = [shape_message(s, c) for s, c in filter_parts(scene.filter_model, spec.condition)]
            obj.graspable = True
            obj.frames = [obj.name]
            msg.objects.append(obj)
    return msg
