"""Planning and executing trajectories of AT instances: the AT server's robot commands.

plan_command resolves the waypoints to world goals and asks the planner node for joint
trajectories; execute_command runs a stored plan, per waypoint the arm trajectory through the
trajectory action and then the gripper pose. Differences from the original, each fixing a defect
it had:

- both answer with their real outcome (the original never filled ``status``);
- a plan is executed only while it still fits the world (robot and registered objects where
  they were at planning time, same object in the gripper), and only once;
- a second robot command while one executes is refused, not queued;
- every wait has a timeout;
- a halt (:mod:`at_ros.halt`) ends an execution at once, HALTED, with the waypoint it reached
  recorded; a plan without ``steps`` after an interrupted execution resumes after that waypoint;
- every plan gets a ``plan_id`` and is kept with what became of it, for ``get_plan``.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from typing import Any

from action_msgs.msg import GoalStatus
from affordance_template_msgs.msg import RegisteredFrame, ServerStatus, WaypointGoal
from affordance_template_msgs.srv import AffordanceTemplateExecuteCommand, AffordanceTemplatePlanCommand, PlanWaypoints
from caretaker_sim_msgs.action import FollowJointTrajectory
from caretaker_sim_msgs.srv import SetGripper

from at_ros.action_client import RecordedActionClient
from at_ros.frames import WORLD_FRAME
from at_ros.halt import Halted, HaltSwitch, Mark
from at_ros.instance import ExecutionOutcome, PlanState, ResolvedWaypoint, StoredPlan, TemplateInstance, path_sequence
from at_ros.messages import pose_from_matrix
from at_ros.server_core import CommandRefused, ServerCore
from ros_process.command_order import stamp
from ros_process.delay_hooks import pause

__all__ = [
    "CANCEL_WAIT_S",
    "PLAN_TIMEOUT",
    "RESULT_ASK_AGAIN_S",
    "PlanExecutor",
    "reached",
    "trajectory_result",
    "wait_for_future",
]

LOG = logging.getLogger(__name__)

PLAN_TIMEOUT = 60.0
#: How long a trajectory goal's result is waited for before it is asked for again.
RESULT_ASK_AGAIN_S = 5.0
#: How long a goal cancelled for want of a result is given to end and say how.
CANCEL_WAIT_S = 10.0
#: How long the joint states are waited for to show the arm where a motion starts.
ARM_AT_START_WAIT_S = 10.0


def _settled(future: Any, timeout: float) -> bool:
    """Whether an rclpy future completed within ``timeout``; one that did not is cancelled."""
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    if done.wait(timeout):
        return True
    future.cancel()
    return False


def _answer(future: Any, what: str) -> Any:
    if future.exception() is not None:
        raise CommandRefused(f"{what} failed: {future.exception()}")
    return future.result()


def wait_for_future(future: Any, timeout: float, what: str) -> Any:
    """The result of an rclpy future, or CommandRefused naming ``what`` on timeout or failure."""
    if not _settled(future, timeout):
        raise CommandRefused(f"{what} did not answer within {timeout:.0f} s")
    return _answer(future, what)


def trajectory_result(handle: Any, timeout: float) -> Any:
    """The result of an accepted trajectory goal, asked for again every :data:`RESULT_ASK_AGAIN_S`.

    A get_result answer lost between the processes would otherwise leave the execution waiting
    out its whole timeout and then report a motion that may have finished as failed. Asking
    only reads (the action server keeps a goal's result), so asking twice cannot move the robot
    twice; the first answer is the result.

    A goal with no result by ``timeout`` is cancelled: a controller that accepted it may still
    start it late, and the arm must not move after its command was answered. Its result is then
    waited for :data:`CANCEL_WAIT_S` more, so the answer says what became of it: finished after
    all (returned), or cancelled before or while it moved. Only if none comes is the motion
    refused as one whose end is not known.
    """
    result = _result_within(handle, timeout)
    if result is not None:
        return result
    LOG.warning("no result of trajectory goal %s within %.0f s: cancelling it", _goal_id(handle), timeout)
    handle.cancel_goal_async()
    result = _result_within(handle, CANCEL_WAIT_S)
    if result is None:
        raise CommandRefused(
            f"the trajectory action did not answer within {timeout:.0f} s, nor {CANCEL_WAIT_S:.0f} s "
            "after its goal was cancelled: whether the arm moves is not known; halt it and check"
        )
    if not reached(result):
        raise CommandRefused(
            f"the trajectory action gave no result within {timeout:.0f} s, so its goal was cancelled: {_said(result)}"
        )
    return result


def reached(outcome: Any) -> bool:
    """Whether a trajectory goal's result says the arm reached its end: the goal SUCCEEDED and
    its error code says so. A goal cancelled mid-motion may carry code SUCCESSFUL (as
    ros2_controllers' own controller does) while the arm stopped short."""
    return bool(
        outcome.status == GoalStatus.STATUS_SUCCEEDED
        and outcome.result.error_code == FollowJointTrajectory.Goal.SUCCESSFUL
    )


def _result_within(handle: Any, timeout: float) -> Any | None:
    """The goal's result if it comes within ``timeout``, asking again every :data:`RESULT_ASK_AGAIN_S`."""
    deadline = time.monotonic() + timeout
    while True:
        future = handle.get_result_async()
        if _settled(future, max(0.0, min(RESULT_ASK_AGAIN_S, deadline - time.monotonic()))):
            return _answer(future, "the trajectory action")
        if time.monotonic() >= deadline:
            return None
        LOG.warning(
            "no result of trajectory goal %s after %.0f s: asking for it again", _goal_id(handle), RESULT_ASK_AGAIN_S
        )


def _goal_id(handle: Any) -> str:
    return bytes(handle.goal_id.uuid).hex()


def _said(outcome: Any) -> str:
    """What a trajectory result that is not a success says of itself."""
    said = outcome.result.error_string or f"error code {outcome.result.error_code}"
    if outcome.status == GoalStatus.STATUS_CANCELED and "cancel" not in said:
        said = f"cancelled ({said}): the arm stopped short of the waypoint"
    return said


class PlanExecutor:
    """plan_command and execute_command on one :class:`ServerCore`, with the node's ROS clients.

    ``gripper_client`` is None for a robot without a gripper service; ``halts`` stops them.
    """

    def __init__(
        self,
        core: ServerCore,
        *,
        planner_client: Any,
        trajectory_client: RecordedActionClient,
        gripper_client: Any | None,
        halts: HaltSwitch,
    ) -> None:
        self.core = core
        self.planner_client = planner_client
        self.trajectory_client = trajectory_client
        self.gripper_client = gripper_client
        self.halts = halts
        self._gripper_pose: str | None = None

    # --- plan ------------------------------------------------------------------------------

    def plan_command(
        self, request: AffordanceTemplatePlanCommand.Request, response: AffordanceTemplatePlanCommand.Response
    ) -> Any:
        core = self.core
        instance = core.instance(request.type, request.id)
        trajectory = instance.trajectory(request.trajectory_name)
        ee = instance.end_effector(trajectory, list(request.end_effectors))
        group = trajectory.group(ee.id)
        assert group is not None
        mark = self.halts.mark(request.issued)  # a halt since the command was issued prevents the execution
        lock = core.command_lock(instance.key)
        if not lock.acquire(timeout=PLAN_TIMEOUT):
            raise CommandRefused(f"{instance.key} is busy with another command")
        try:
            with core.state_lock:
                if core.state.executing:
                    raise CommandRefused(f"the robot is executing {core.state.executing}; plan after it finishes")
                progress = instance.progress[trajectory.name]
                steps = int(request.steps[0]) if len(request.steps) else None
                indices = path_sequence(
                    len(group.waypoints),
                    progress.current_index,
                    steps,
                    direct=request.direct,
                    backwards=request.backwards,
                    resume=progress.interrupted,
                )
                resolved = instance.resolve(trajectory, ee)
                joints = dict(core.inputs.joints)
                held = core.inputs.held_object
                registrations = dict(instance.registrations)
                instance.current_trajectory = trajectory.name
                instance.invalidate_plan(f"dropped: {trajectory.name!r} is planned again")
            core.set_state(
                plan_status=ServerStatus.PLAN_PLANNING, active_template=instance.key, active_trajectory=trajectory.name
            )
            try:
                segments = self._request_plan([resolved[i] for i in indices], joints, held)
            except CommandRefused as exc:
                core.set_state(plan_status=ServerStatus.PLAN_FAILED)
                raise CommandRefused(f"planning {trajectory.name!r} of {instance.key} failed: {exc}") from exc
            with core.state_lock:
                instance.plan = StoredPlan(
                    trajectory=trajectory.name,
                    end_effector=ee.name,
                    indices=indices,
                    segments=segments,
                    start_joints={j: joints[j] for j in core.robot.joint_names},
                    registrations=registrations,
                    held_object=held,
                    plan_id=uuid.uuid4().hex,
                )
                instance.plans[trajectory.name] = instance.plan
                progress.plan_index = indices[-1]
            core.set_state(plan_status=ServerStatus.PLAN_PLANNED)
        finally:
            lock.release()
        message = f"planned {trajectory.name!r} of {instance.key}: waypoints {indices}"
        if request.execute:
            message += "; " + self._execute(instance, trajectory.name, mark)
        response.affordance_template_status = core.instance_status(instance, trajectory.name)
        return core.succeed(response, message)

    def _request_plan(self, waypoints: list[ResolvedWaypoint], joints: dict[str, float], held: str) -> list[Any]:
        robot = self.core.robot
        missing = [j for j in robot.joint_names if j not in joints]
        if missing:
            raise CommandRefused(f"no joint_states for {missing} yet; is the simulation running?")
        if not self.planner_client.wait_for_service(timeout_sec=2.0):
            raise CommandRefused(
                f"the planner node does not answer on {self.planner_client.srv_name}; "
                "start `caretaker planner --robot NAME`"
            )
        request = PlanWaypoints.Request()
        request.robot_name = robot.robot_name
        request.start_state.name = list(robot.joint_names)
        request.start_state.position = [float(joints[j]) for j in robot.joint_names]
        request.held_object = held
        with self.core.state_lock:
            registered = list(self.core.registered.values())
        for registration in registered:
            located = RegisteredFrame()
            located.frame = registration.frame
            located.pose = pose_from_matrix(registration.world)
            located.against = pose_from_matrix(registration.frame_pose)
            request.registered.append(located)
        for wp in waypoints:
            goal = WaypointGoal()
            goal.label = wp.label
            goal.source = wp.source
            goal.pose.header.frame_id = WORLD_FRAME
            goal.pose.pose = pose_from_matrix(wp.tool_goal)
            goal.planner_type = wp.waypoint.planner_type
            goal.end_effector_pose = wp.end_effector_pose
            # Tight: a 0.01 rad tilt at the gripper is 2 mm at the far end of a carried filter.
            goal.position_tolerance = 5e-4
            goal.orientation_tolerance = 2e-3
            goal.gripper_action = wp.gripper_action
            goal.object_name = wp.object_name
            if wp.object_pose is not None:
                goal.object_pose = pose_from_matrix(wp.object_pose)
            request.waypoints.append(goal)
        result = wait_for_future(self.planner_client.call_async(request), PLAN_TIMEOUT, "the planner")
        if not result.success:
            raise CommandRefused(result.message)
        return list(result.segments)

    # --- execute ---------------------------------------------------------------------------

    def execute_command(
        self, request: AffordanceTemplateExecuteCommand.Request, response: AffordanceTemplateExecuteCommand.Response
    ) -> Any:
        core = self.core
        instance = core.instance(request.type, request.id)
        trajectory = instance.trajectory(request.trajectory_name)
        if request.end_effectors:
            instance.end_effector(trajectory, list(request.end_effectors))
        message = self._execute(instance, trajectory.name, self.halts.mark(request.issued))
        response.affordance_template_status = core.instance_status(instance, trajectory.name)
        return core.succeed(response, message)

    def _execute(self, instance: TemplateInstance, trajectory: str, mark: Mark) -> str:
        """Run the stored plan of ``trajectory``; a halt after ``mark`` stops it (or prevents it)."""
        core = self.core
        if not core.robot_lock.acquire(blocking=False):
            with core.state_lock:
                busy = core.state.executing
            raise CommandRefused(
                f"the robot is executing {busy or 'another command'}; this command was refused, not queued"
            )
        try:
            with core.state_lock:
                plan = instance.plan
                if plan is None or plan.trajectory != trajectory:
                    raise CommandRefused(f"no valid plan for {trajectory!r} of {instance.key}; call plan_command first")
                reason = core.stale_reason(instance, plan)
                if reason is not None:
                    raise CommandRefused(f"the plan for {trajectory!r} of {instance.key} is no longer valid: {reason}")
                halted = self.halts.halted_since(mark)
                if halted is not None:
                    instance.invalidate_plan(f"halted before it ran ({halted})")
                    core.state.halt_reason = halted
                else:
                    core.state.executing = instance.key
                    plan.set_state(PlanState.EXECUTING, "executing")
                    instance.plan = None  # a plan runs once; the robot is about to leave its start
            if halted is not None:
                core.set_state(
                    execute_status=ServerStatus.EXECUTE_HALTED,
                    active_template=instance.key,
                    active_trajectory=trajectory,
                )
                raise Halted(
                    halted,
                    f"halted ({halted}) before executing {trajectory!r} of {instance.key}: nothing moved; plan again",
                )
            core.set_state(
                execute_status=ServerStatus.EXECUTE_EXECUTING,
                active_template=instance.key,
                active_trajectory=trajectory,
            )
            progress = instance.progress[trajectory]
            progress.execution_valid = False
            # Recorded before anything moves: a server that dies now is seen, after its restart,
            # as having been interrupted here.
            self._record(
                instance, trajectory, ExecutionOutcome.EXECUTING, f"executing {trajectory!r} of {instance.key}"
            )
            # Command the first gripper pose even if it seems unchanged: something else may have moved it.
            self._gripper_pose = None
            try:
                for index, segment in zip(plan.indices, plan.segments, strict=False):
                    self._run_segment(segment, mark)
                    progress.current_index = index
                    self._record(
                        instance,
                        trajectory,
                        ExecutionOutcome.EXECUTING,
                        f"{instance.key} reached waypoint {index} of {trajectory!r}",
                    )
            except Exception as exc:  # whatever stopped the robot, the status must not stay EXECUTING
                raise self._interrupted(instance, plan, exc, mark) from exc
            progress.execution_valid = True
            done = f"executed {trajectory!r} of {instance.key}: waypoints {plan.indices}"
            plan.set_state(PlanState.EXECUTED, done)
            core.set_state(execute_status=ServerStatus.EXECUTE_SUCCEEDED)
            self._record(instance, trajectory, ExecutionOutcome.SUCCEEDED, done, strict=True)
            return done
        finally:
            with core.state_lock:
                core.state.executing = ""
            core.robot_lock.release()

    def _interrupted(self, instance: TemplateInstance, plan: StoredPlan, exc: Exception, mark: Mark) -> CommandRefused:
        """Record an execution that stopped part-way (halted or failed); the error to answer with."""
        core = self.core
        trajectory = plan.trajectory
        reached = instance.progress[trajectory].current_index
        where = f"after waypoint {reached}" if reached >= 0 else "before its first waypoint"
        halted = self.halts.halted_since(mark)
        if halted is not None:
            outcome, state, status = ExecutionOutcome.HALTED, PlanState.HALTED, ServerStatus.EXECUTE_HALTED
            message = (
                f"halted ({halted}): {instance.key} stopped {where} of {trajectory!r}; "
                "plan again to go on from where the arm is"
            )
        else:
            outcome, state, status = ExecutionOutcome.FAILED, PlanState.FAILED, ServerStatus.EXECUTE_FAILED
            reason = str(exc) if isinstance(exc, CommandRefused) else repr(exc)
            message = f"executing {trajectory!r} of {instance.key} failed {where}: {reason}"
        plan.set_state(state, message)
        with core.state_lock:
            core.state.halt_reason = halted or ""
        core.set_state(execute_status=status)
        try:
            self._record(instance, trajectory, outcome, message, strict=True)
        except CommandRefused as unsaved:
            message += f"; {unsaved}"
        return Halted(halted, message) if halted is not None else CommandRefused(message)

    def _record(
        self, instance: TemplateInstance, trajectory: str, outcome: str, message: str, *, strict: bool = False
    ) -> None:
        """Note how the execution stands and write it to the state file. Mid-motion (not
        ``strict``) a failed write is logged, not raised: stopping the arm would not help it."""
        with self.core.state_lock:
            progress = instance.progress[trajectory]
            progress.outcome, progress.outcome_message = outcome, message
        try:
            self.core.save_instances(message)
        except CommandRefused as exc:
            if strict:
                raise
            LOG.error("%s", exc)

    def _run_segment(self, segment: Any, mark: Mark) -> None:
        """One planned waypoint (affordance_template_msgs/PlannedSegment): arm, then gripper.
        A halt after ``mark`` stops it before each motion, or during one (the robot stops); each
        motion request says when its command was issued, so the robot refuses it after a halt."""
        robot = self.core.robot
        points = segment.arm_trajectory.points
        if len(points) >= 2:
            self.halts.check(mark, f"before the motion to waypoint {segment.label}")  # before waiting for the arm
            if not self.trajectory_client.wait_for_server(timeout_sec=5.0):  # type: ignore[no-untyped-call]
                raise CommandRefused(f"the trajectory action {robot.trajectory_action} is not available")
            away = self.core.arm_away_from(
                dict(zip(segment.arm_trajectory.joint_names, points[0].positions, strict=False)), ARM_AT_START_WAIT_S
            )
            if away is not None:  # said here in words, not left to the controller's refusal
                raise CommandRefused(
                    f"the arm is not where the motion to waypoint {segment.label} starts ({away}); "
                    "nothing was sent: plan again from where the arm is"
                )
            goal = FollowJointTrajectory.Goal()
            goal.trajectory = segment.arm_trajectory
            goal.issued = stamp(mark.issued)
            motion = f"before the motion to waypoint {segment.label}"
            pause("at_server.send_goal")
            try:
                handle = wait_for_future(
                    self.halts.send_goal(self.trajectory_client, goal, mark, motion), 10.0, "the trajectory action"
                )
                if not handle.accepted:
                    raise CommandRefused(f"waypoint {segment.label}: the controller rejected the trajectory")
                self.halts.goal_started(handle, mark)
                last = points[-1].time_from_start
                outcome = trajectory_result(handle, 30.0 + 3.0 * (last.sec + last.nanosec * 1e-9))
            finally:
                self.halts.goal_ended()
            if not reached(outcome):
                raise CommandRefused(f"waypoint {segment.label}: {_said(outcome)}")
        pose = segment.end_effector_pose
        if pose and self.gripper_client is not None and pose != self._gripper_pose:
            self.halts.check(mark, f"before the gripper motion of waypoint {segment.label}")
            if not self.gripper_client.wait_for_service(timeout_sec=5.0):
                raise CommandRefused(f"the gripper service {robot.gripper_service} is not available")
            request = SetGripper.Request()
            request.pose = pose
            request.issued = stamp(mark.issued)
            result = wait_for_future(self.gripper_client.call_async(request), 30.0, "the gripper")
            if not result.success:
                raise CommandRefused(f"waypoint {segment.label}: gripper {pose!r} failed: {result.message}")
            self._gripper_pose = pose
            with self.core.state_lock:
                self.core.inputs.held_object = result.held_object
