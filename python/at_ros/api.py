"""The AT server's ROS API in one place: service names and types, topics, QoS.

The server creates exactly these services; clients (tests, tools) look them up here instead of
repeating the table, so a renamed service cannot drift between them. Names are relative to the
node's namespace (none by default: ``/affordance_template_server/...``).
"""

from __future__ import annotations

from affordance_template_msgs.srv import (
    AddAffordanceTemplate,
    AffordanceTemplateExecuteCommand,
    AffordanceTemplatePlanCommand,
    DeleteAffordanceTemplate,
    GetAffordanceTemplateConfigInfo,
    GetAffordanceTemplateServerStatus,
    GetAffordanceTemplateStatus,
    GetPlan,
    GetRobotConfigInfo,
    GetRunningAffordanceTemplates,
    Halt,
    SetObjectPose,
    SetWaypointPose,
)
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

__all__ = ["LATCHED", "PREFIX", "SERVICES", "SERVICE_QOS", "STATUS_TOPIC"]

#: Relative, so a server started with ``--namespace /arm2`` serves ``/arm2/affordance_template_server``.
PREFIX = "affordance_template_server"
STATUS_TOPIC = f"{PREFIX}/status"
#: service name (under PREFIX) -> service type
SERVICES: dict[str, type] = {
    "add_template": AddAffordanceTemplate,
    "delete_template": DeleteAffordanceTemplate,
    "get_running": GetRunningAffordanceTemplates,
    "get_templates": GetAffordanceTemplateConfigInfo,
    "get_robots": GetRobotConfigInfo,
    "plan_command": AffordanceTemplatePlanCommand,
    "execute_command": AffordanceTemplateExecuteCommand,
    "set_object_pose": SetObjectPose,
    "set_waypoint_pose": SetWaypointPose,
    "get_template_status": GetAffordanceTemplateStatus,
    "get_status": GetAffordanceTemplateServerStatus,
    "get_plan": GetPlan,
    "halt": Halt,
}
#: The simulation latches robot/moving, gripper/held_object and the CDRA telemetry: subscribe with
#: this to get the last value at once.
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
#: Services and their clients keep this many requests (responses) queued. ROS's default of 10
#: drops requests silently once more than 10 arrive together (several web views polling).
SERVICE_QOS = QoSProfile(depth=1000, durability=DurabilityPolicy.VOLATILE, reliability=ReliabilityPolicy.RELIABLE)
