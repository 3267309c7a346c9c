"""The AT server's services for instances and registration, and the status queries.

add/delete/get_running/get_templates/get_robots keep the original's names and behaviour
(instances ``Type:id`` with the lowest free id); set_object_pose registers a display object to a
named frame with an offset, set_waypoint_pose moves one waypoint (the original had no such
service). A request that fails changes nothing.
"""

from __future__ import annotations

from typing import Any

from affordance_template_msgs.srv import (
    AddAffordanceTemplate,
    DeleteAffordanceTemplate,
    GetAffordanceTemplateStatus,
    SetObjectPose,
    SetWaypointPose,
)

from at_ros.frames import WORLD_FRAME
from at_ros.instance import InstanceError, Registration, TemplateInstance, next_free_id
from at_ros.messages import matrix_from_pose
from at_ros.server_core import FRAME_WAIT, CommandRefused, ServerCore
from at_ros.template_messages import robot_config_message, template_config

__all__ = ["InstanceServices"]


class InstanceServices:
    """Callbacks of the instance, registration and query services, on one :class:`ServerCore`."""

    def __init__(self, core: ServerCore) -> None:
        self.core = core

    # --- instances -------------------------------------------------------------------------

    def add_template(self, request: AddAffordanceTemplate.Request, response: AddAffordanceTemplate.Response) -> Any:
        core = self.core
        template = core.template(request.class_type)
        frame = request.pose.header.frame_id
        if frame:
            root = core.frames.lookup(frame, FRAME_WAIT) @ matrix_from_pose(request.pose.pose)
        else:
            # The original placed new instances at the robot config's root_offset in frame_id.
            root = core.frames.lookup(core.robot.frame_id, FRAME_WAIT) @ core.robot.root_offset_matrix
        with core.state_lock:
            used = {i.id for i in core.state.instances.values() if i.template.name == template.name}
            instance = TemplateInstance(
                template, next_free_id(used), core.robot, root, hide_waypoints=request.hide_waypoints
            )
            core.state.instances[instance.key] = instance
        response.id = instance.id
        response.instance = instance.key
        core.save_instances(f"added {instance.key}")
        return core.succeed(response, f"added {instance.key}")

    def delete_template(
        self, request: DeleteAffordanceTemplate.Request, response: DeleteAffordanceTemplate.Response
    ) -> Any:
        core = self.core
        instance = core.instance(request.class_type, request.id)
        with core.state_lock:
            if core.state.executing == instance.key:
                raise CommandRefused(f"{instance.key} is executing; wait for it to finish before deleting it")
            del core.state.instances[instance.key]
            if core.state.active_template == instance.key:
                core.state.active_template = ""
                core.state.active_trajectory = ""
        core.save_instances(f"deleted {instance.key}")
        return core.succeed(response, f"deleted {instance.key}")

    def get_running(self, request: Any, response: Any) -> Any:
        with self.core.state_lock:
            response.templates = sorted(self.core.state.instances)
        response.success = True
        response.message = f"{len(response.templates)} running"
        return response

    def get_templates(self, request: Any, response: Any) -> Any:
        core = self.core
        if request.name:
            core.template(request.name)
        names = [request.name] if request.name else sorted(core.templates)
        response.templates = [template_config(core.templates[n], core.robot) for n in names]
        response.success = True
        response.message = f"{len(names)} templates"
        return response

    def get_robots(self, request: Any, response: Any) -> Any:
        robots = self.core.robots
        if request.name and request.name not in robots:
            raise InstanceError(f"unknown robot {request.name!r}; known: {', '.join(sorted(robots))}")
        names = [request.name] if request.name else sorted(robots)
        response.robots = [robot_config_message(robots[n]) for n in names]
        response.success = True
        response.message = f"{len(names)} robots"
        return response

    # --- registration ----------------------------------------------------------------------

    def set_object_pose(self, request: SetObjectPose.Request, response: SetObjectPose.Response) -> Any:
        core = self.core
        if not request.objects:
            raise CommandRefused("no objects given; pass one DisplayObjectInfo per object to register")
        # Check everything first: a request that fails changes nothing.
        updates = []
        for obj in request.objects:
            instance = core.instance(obj.type, obj.id)
            name = obj.name.split(":")[0]  # accept "cdra_filter" and the frame name "cdra_filter:0"
            if instance.template.display_object(name) is None:
                raise InstanceError(
                    f"template {instance.template.name!r} has no display object {name!r}; "
                    f"it has: {', '.join(o.name for o in instance.template.display_objects)}"
                )
            frame = obj.stamped_pose.header.frame_id or WORLD_FRAME
            frame_pose = core.frames.lookup(frame, FRAME_WAIT)
            updates.append((instance, name, Registration(frame, matrix_from_pose(obj.stamped_pose.pose), frame_pose)))
        for instance, name, registration in updates:
            with core.command_lock(instance.key), core.state_lock:
                instance.register(name, registration)
                if registration.frame != WORLD_FRAME:  # the world frame is where it is by definition
                    core.registered.pop(registration.frame, None)  # the latest last
                    core.registered[registration.frame] = registration
        done = "registered " + ", ".join(f"{n}:{i.id} to {r.frame}" for i, n, r in updates)
        core.save_instances(done)
        return core.succeed(response, done)

    def set_waypoint_pose(self, request: SetWaypointPose.Request, response: SetWaypointPose.Response) -> Any:
        core = self.core
        instance = core.instance(request.type, request.id)
        trajectory = instance.trajectory(request.trajectory_name)
        ee = instance.end_effector(trajectory, [request.end_effector] if request.end_effector else [])
        group = trajectory.group(ee.id)
        assert group is not None
        if not 0 <= request.waypoint_id < len(group.waypoints):
            raise InstanceError(
                f"trajectory {trajectory.name!r} has waypoints 0..{len(group.waypoints) - 1} "
                f"for {ee.name!r}, not {request.waypoint_id}"
            )
        frame = request.pose.header.frame_id
        with core.command_lock(instance.key), core.state_lock:
            if frame:
                parent = core.frames.lookup(frame)
            else:
                parent = instance.object_pose(group.waypoints[request.waypoint_id].display_object)
            instance.set_waypoint(trajectory, ee, request.waypoint_id, parent @ matrix_from_pose(request.pose.pose))
        done = f"moved waypoint {ee.id}.{request.waypoint_id}:{instance.key} of {trajectory.name!r}"
        core.save_instances(done)
        return core.succeed(response, done)

    # --- queries ---------------------------------------------------------------------------

    def get_template_status(
        self, request: GetAffordanceTemplateStatus.Request, response: GetAffordanceTemplateStatus.Response
    ) -> Any:
        core = self.core
        instance = core.instance_named(request.name)
        names = (
            [instance.trajectory(request.trajectory_name).name]
            if request.trajectory_name
            else instance.template.trajectory_names
        )
        response.affordance_template_status = [core.instance_status(instance, n, request.frame_id) for n in names]
        response.current_trajectory = instance.current_trajectory
        response.trajectory_names = instance.template.trajectory_names
        response.success = True
        response.message = f"status of {instance.key}"
        return response
