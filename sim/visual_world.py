"""What a scene looks like, as the ``VisualWorld`` message the simulation latches for views.

A view on the ground (issue 17's 3D view) draws the habitat as the habitat has it, from data
sent once: every body with its shapes and colours (the collision world's bodies plus what is
drawn only: inspection targets, the cabinet's lock lamp), the robot's root pose and joint
names. The robot's geometry is its URDF (``robot_description``); what moves afterwards comes
on ``sim/frames`` (poses by name) and ``joint_states``, so nothing here is sent again.
"""

from __future__ import annotations

from caretaker_sim_msgs.msg import CollisionObject, VisualWorld

from sim.cdra_cabinet import LOCKED_COLOR, UNLOCKED_COLOR
from sim.collision_world import collision_world, pose_message, shape_message
from sim.scene import Pose, Scene, Shape, target_parts

__all__ = ["LAMP_NAME", "visual_world"]

#: The cabinet's lock lamp: red while locked, green while unlocked (cdra/filter_locked says which).
LAMP_NAME = "cabinet/lamp"


def visual_world(scene: Scene) -> VisualWorld:
    """Every object ``scene`` draws, in its starting state, plus the robot's root and joints."""
    msg = VisualWorld()
    msg.scene = scene.name
    msg.robot_name = scene.robot.name
    msg.robot_base = pose_message(scene.robot.base)
    msg.arm_joints = list(scene.robot.arm_joints)
    msg.gripper_joints = list(scene.robot.gripper.joints) if scene.robot.gripper else []
    msg.tool_link = scene.robot.tool_link
    msg.objects = list(collision_world(scene).objects)
    if scene.target_model is not None:
        for target in scene.targets:
            obj = CollisionObject()
            obj.name = f"target/{target.name}"
            obj.pose = pose_message(target.pose)
            obj.shapes = [shape_message(s, c) for s, c in target_parts(scene.target_model, target.condition)]
            msg.objects.append(obj)
    if scene.cabinet is not None:
        # Placed as sim.world places it: at latch_pose's position in the slot frame.
        slot = scene.slots[scene.cabinet.slot].pose
        lamp = CollisionObject()
        lamp.name = LAMP_NAME
        lamp.pose = pose_message(slot)
        color = LOCKED_COLOR if scene.cabinet.locked else UNLOCKED_COLOR
        lamp.shapes = [
            shape_message(Shape("box", Pose(scene.cabinet.latch_pose.xyz), size=scene.cabinet.latch_size), color)
        ]
        msg.objects.append(lamp)
    return msg
