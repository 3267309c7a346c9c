"""What every part of the AT server shares: the robot, the library, the world, the instances, the locks.

The server is split by concept — status (this module and the node), instances and registration
(:mod:`at_ros.instance_services`), plan and execute (:mod:`at_ros.plan_execute`) — and each part
works on one :class:`ServerCore`. Locks: ``state_lock`` guards the instance table, the status
fields and the robot inputs; ``robot_lock`` is held while the robot executes; each instance's
command lock serializes commands on that instance.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from affordance_template_msgs.msg import AffordanceTemplateStatus, ServerStatus

from at_ros.frames import WORLD_FRAME, FrameTable, UnknownFrame
from at_ros.instance import InstanceError, Registration, StoredPlan, TemplateInstance
from at_ros.instance_store import save_instances
from at_ros.library import LibraryError, Template, load_library
from at_ros.robot_config import RobotConfig
from at_ros.template_messages import instance_status

__all__ = [
    "CommandRefused",
    "RobotInputs",
    "ServerCore",
    "ServerState",
    "HEARTBEAT_TIMEOUT",
    "JOINT_TOLERANCE",
    "FRAME_WAIT",
    "START_TOLERANCE",
]

HEARTBEAT_TIMEOUT = 5.0  # s; a plan may hold the planner's GIL for a few seconds
JOINT_TOLERANCE = 0.02  # rad the robot may drift from a plan's start and still run it
#: rad a motion's first point may be from the arm: what trajectory controllers accept as a start.
START_TOLERANCE = 0.01
FRAME_WAIT = 3.0  # s to wait for a frame not (yet) published, as the original waited for TF


class CommandRefused(Exception):
    """A command that cannot run now or as asked; the message says what to fix."""


@dataclass
class ServerState:
    """What the status topic reports; guarded by ``ServerCore.state_lock``."""

    plan_status: str = ServerStatus.PLAN_IDLE
    execute_status: str = ServerStatus.EXECUTE_IDLE
    active_template: str = ""
    active_trajectory: str = ""
    last_error: str = ""
    halt_reason: str = ""  # of the halt that ended the last execution, while execute_status is HALTED
    executing: str = ""  # "Type:id" while the robot executes
    instances: dict[str, TemplateInstance] = field(default_factory=dict)


@dataclass
class RobotInputs:
    """What the server last heard from the robot side; guarded by ``ServerCore.state_lock``."""

    joints: dict[str, float] = field(default_factory=dict)
    joints_stamp: Any = None  # builtin_interfaces/Time of the latest joint_states: the robot's clock
    moving: bool = False
    held_object: str = ""
    last_heartbeat: float = 0.0  # time.monotonic() of the planner's last heartbeat


class ServerCore:
    """Shared state of one AT server and the operations every service needs on it.

    ``publish_status`` is set by the node: it publishes ``ServerStatus`` if something changed.
    """

    def __init__(
        self,
        robot: RobotConfig,
        templates: dict[str, Template],
        robots: dict[str, RobotConfig],
        *,
        template_folder: Path | None,
        state_file: Path | None,
        instances: dict[str, TemplateInstance],
    ) -> None:
        self.robot = robot
        self.templates = templates
        self.robots = robots
        self.template_folder = template_folder
        self.state_file = state_file
        self.frames = FrameTable()
        self.state = ServerState(instances=instances)
        #: The latest registration of each named frame, oldest first: where the runs located things
        #: (the planner's world follows them, at_ros.registered_world). After a restart, what the
        #: instances are registered to now (an instance moved on from a frame took that with it).
        self.registered: dict[str, Registration] = {
            r.frame: r for i in instances.values() for r in i.registrations.values() if r.frame != WORLD_FRAME
        }
        self.inputs = RobotInputs()
        self.state_lock = threading.RLock()
        #: Notified (under ``state_lock``) whenever joint states arrive.
        self.joints_heard = threading.Condition(self.state_lock)
        self.robot_lock = threading.Lock()
        self._command_locks: dict[str, threading.Lock] = {}
        self.publish_status: Callable[[], None] = lambda: None

    # --- lookups ---------------------------------------------------------------------------

    def template(self, name: str) -> Template:
        """The template called ``name``, re-reading the library folder once if it is not loaded yet,
        so adding a template is dropping a JSON file in the library: no restart, no code.

        Raises:
            InstanceError: no such template, or the library no longer loads (the message says why).
        """
        template = self.templates.get(name)
        if template is None and self.template_folder is not None:
            try:
                self.templates = load_library(self.template_folder)
            except LibraryError as exc:
                raise InstanceError(f"unknown template {name!r}, and the library does not reload: {exc}") from None
            template = self.templates.get(name)
        if template is None:
            raise InstanceError(f"unknown template {name!r}; the library has: {', '.join(sorted(self.templates))}")
        return template

    def instance_named(self, name: str) -> TemplateInstance:
        """The instance called ``name`` ("Type:id"), as status queries name it."""
        type_name, _, id_text = name.partition(":")
        if not id_text.isdigit():
            raise InstanceError(f"name must be 'Type:id' (e.g. 'cdra_filter:0'), got {name!r}")
        return self.instance(type_name, int(id_text))

    def instance(self, type_name: str, instance_id: int) -> TemplateInstance:
        key = f"{type_name}:{instance_id}"
        with self.state_lock:
            instance = self.state.instances.get(key)
            running = sorted(self.state.instances)
        if instance is None:
            self.template(type_name)
            raise InstanceError(
                f"no running instance {key!r}; running: {', '.join(running) or 'none'} (add_template first)"
            )
        return instance

    def command_lock(self, key: str) -> threading.Lock:
        with self.state_lock:
            return self._command_locks.setdefault(key, threading.Lock())

    # --- changes ---------------------------------------------------------------------------

    def save_instances(self, done: str) -> None:
        """Write the instances to the state file after a change; ``done`` says what changed.

        The change has happened either way; a failed write is refused loudly, because a restart
        would lose it.
        """
        if self.state_file is None:
            return
        try:
            with self.state_lock:
                save_instances(self.state_file, self.robot, self.state.instances)
        except OSError as exc:
            raise CommandRefused(
                f"{done}, but the state file {self.state_file} could not be written ({exc}): a restart would lose it"
            ) from exc

    def set_state(self, **fields: str) -> None:
        with self.state_lock:
            for name, value in fields.items():
                setattr(self.state, name, value)
            if self.state.execute_status != ServerStatus.EXECUTE_HALTED:
                self.state.halt_reason = ""
        self.publish_status()

    def succeed(self, response: Any, message: str) -> Any:
        response.success = True
        response.message = message
        with self.state_lock:
            self.state.last_error = ""
        self.publish_status()
        return response

    def refuse(self, name: str, response: Any, message: str) -> Any:
        response.success = False
        response.message = message
        with self.state_lock:
            self.state.last_error = f"{name}: {message}"
        self.publish_status()
        return response

    # --- validity and status ---------------------------------------------------------------

    def arm_away_from(self, positions: dict[str, float], timeout: float) -> str | None:
        """None once the joint states heard put the arm within :data:`START_TOLERANCE` of
        ``positions``; after ``timeout`` without that, which joint is how far off, in words.

        Waits on joint states, not a time: right after a motion ends, the states last heard can
        still be from before its end (more so on a starved machine), and are not yet where it ended.
        """

        def worst() -> tuple[float, str]:
            joints = self.inputs.joints
            return max(
                ((abs(joints[j] - q) if j in joints else float("inf"), j) for j, q in positions.items()),
                default=(0.0, ""),
            )

        with self.joints_heard:
            if self.joints_heard.wait_for(lambda: worst()[0] <= START_TOLERANCE, timeout):
                return None
            distance, joint = worst()
        if distance == float("inf"):
            return f"no joint state of {joint} was heard"
        return f"{joint} is {distance:.3f} rad ({math.degrees(distance):.1f}°) from where the motion starts"

    def stale_reason(self, instance: TemplateInstance, plan: StoredPlan) -> str | None:
        """Why ``plan`` no longer fits the world now, or None (call with ``state_lock`` held)."""
        return instance.stale_reason(
            plan, self.frames.snapshot(), dict(self.inputs.joints), self.inputs.held_object, JOINT_TOLERANCE
        )

    def plan_valid(self) -> bool:
        with self.state_lock:
            instance = self.state.instances.get(self.state.active_template)
            plan = instance.plan if instance else None
            return instance is not None and plan is not None and self.stale_reason(instance, plan) is None

    def status_message(self, stamp: Any) -> ServerStatus:
        """The SysRep telemetry and the server's state, as the status topic carries it."""
        plan_valid = self.plan_valid()
        with self.state_lock:
            msg = ServerStatus()
            msg.stamp = stamp
            msg.robot_name = self.robot.robot_name
            msg.robot_active = self.inputs.moving
            msg.planner_node_active = time.monotonic() - self.inputs.last_heartbeat < HEARTBEAT_TIMEOUT
            msg.affordance_template_server_active = True
            msg.execute_status = self.state.execute_status
            msg.plan_status = self.state.plan_status
            msg.plan_valid = plan_valid
            msg.active_template = self.state.active_template
            msg.active_trajectory = self.state.active_trajectory
            msg.running_templates = sorted(self.state.instances)
            msg.last_error = self.state.last_error
            msg.halt_reason = self.state.halt_reason
            active = self.state.instances.get(self.state.active_template)
            plan = active.plans.get(self.state.active_trajectory) if active else None
            msg.plan_id = plan.plan_id if plan else ""
        return msg

    def instance_status(self, instance: TemplateInstance, trajectory: str, frame: str = "") -> AffordanceTemplateStatus:
        """One trajectory of ``instance`` as the original's AffordanceTemplateStatus, in ``frame``."""
        frame = frame or self.robot.frame_id
        try:
            frame_pose = self.frames.lookup(frame)
        except UnknownFrame:
            if frame != self.robot.frame_id:
                raise
            frame, frame_pose = WORLD_FRAME, self.frames.lookup(WORLD_FRAME)
        with self.state_lock:
            active = self.state.active_template == instance.key and self.state.active_trajectory == trajectory
            plan_status = self.state.plan_status if active else ServerStatus.PLAN_IDLE
            execute_status = self.state.execute_status if active else ServerStatus.EXECUTE_IDLE
            plan = instance.plan
            valid = plan is not None and plan.trajectory == trajectory and self.stale_reason(instance, plan) is None
            return instance_status(
                instance,
                trajectory,
                frame,
                frame_pose,
                plan_status=plan_status,
                execute_status=execute_status,
                plan_valid=valid,
            )
