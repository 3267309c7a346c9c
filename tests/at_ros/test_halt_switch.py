"""HaltSwitch in-process: what a halt stops and says for a robot without a halt service, and how
a command learns of a halt (the real stack's halt is tests/at_ros/test_halt.py)."""

from __future__ import annotations

import threading

import pytest
from affordance_template_msgs.srv import Halt
from builtin_interfaces.msg import Time
from caretaker_sim_msgs.srv import Halt as RobotHalt
from rclpy.task import Future

from at_ros.halt import Halted, HaltSwitch
from at_ros.robot_config import load_robot_configs
from at_ros.server_core import ServerCore
from ros_process.command_order import arrived_now, stamp


class GoalHandle:
    """Stands in for rclpy's ClientGoalHandle: counts cancels."""

    def __init__(self) -> None:
        self.cancels = 0

    def cancel_goal_async(self) -> None:
        self.cancels += 1


@pytest.fixture()
def switch() -> HaltSwitch:
    core = ServerCore(load_robot_configs()["ur10"], {}, {}, template_folder=None, state_file=None, instances={})
    return HaltSwitch(core, halt_client=None)


def _halt(switch: HaltSwitch, reason: str = "ops: Halt") -> Halt.Response:
    return switch.halt(Halt.Request(reason=reason), Halt.Response())


def test_without_a_halt_service_a_halt_cancels_the_goal_in_flight(switch: HaltSwitch) -> None:
    mark = switch.mark()
    goal = GoalHandle()
    switch.goal_started(goal, mark)
    switch.core.state.executing = "cdra_filter:0"
    response = _halt(switch)
    assert goal.cancels == 1 and response.success and response.halted == "cdra_filter:0"
    assert "cancelled the trajectory goal" in response.message and "gripper motion goes on" in response.message
    with pytest.raises(Halted, match=r"halted \(ops: Halt\) before the next waypoint") as raised:
        switch.check(mark, "before the next waypoint")
    assert raised.value.reason == "ops: Halt"


def test_a_goal_accepted_after_the_halt_is_cancelled_at_once(switch: HaltSwitch) -> None:
    mark = switch.mark()
    _halt(switch)
    late = GoalHandle()
    switch.goal_started(late, mark)
    assert late.cancels == 1
    switch.goal_ended()
    fresh = GoalHandle()
    switch.goal_started(fresh, switch.mark())  # a command begun after the halt runs
    assert fresh.cancels == 0 and switch.halted_since(switch.mark()) is None


def test_a_command_issued_before_a_halt_is_halted_however_late_it_reaches_the_server(switch: HaltSwitch) -> None:
    _halt(switch)
    held = switch.mark(stamp(arrived_now() - 60.0))  # the ledger had it a minute before the halt came
    with pytest.raises(Halted, match=r"halted \(ops: Halt\) before executing"):
        switch.check(held, "before executing")
    assert switch.halted_since(switch.mark(Time())) is None  # unstamped: issued when it arrives, after the halt


def test_with_nothing_moving_it_says_so_and_when_it_cannot_tell_it_says_that(switch: HaltSwitch) -> None:
    response = _halt(switch, "")
    assert response.success and response.message == "nothing was moving" and response.halted == ""
    switch.core.inputs.moving = True  # moving, but not by this server's command
    response = _halt(switch)
    assert (
        not response.success
        and response.message.startswith("not confirmed: the robot moves")
        and "halt_service" in response.message
    )


class TrajectoryClient:
    """Stands in for rclpy's ActionClient: each goal's answer is an rclpy Future the test settles."""

    def __init__(self) -> None:
        self.sent: list[Future] = []

    def send_goal_async(self, goal: object) -> Future:
        self.sent.append(Future())
        return self.sent[-1]


class Accepted(GoalHandle):
    accepted = True


class RobotHaltClient:
    """Stands in for the robot's halt service client: notes when it was called."""

    srv_name = "robot/halt"

    def __init__(self, calls: list[str]) -> None:
        self.calls = calls

    def wait_for_service(self, timeout_sec: float) -> bool:
        return True

    def call_async(self, request: object) -> Future:
        self.calls.append("robot halted")
        future = Future()
        future.set_result(RobotHalt.Response(success=True, stopped=False, message="nothing was moving"))
        return future


def test_no_goal_leaves_after_a_halt(switch: HaltSwitch) -> None:
    mark = switch.mark()
    _halt(switch)
    client = TrajectoryClient()
    with pytest.raises(Halted, match=r"halted \(ops: Halt\) before the motion"):
        switch.send_goal(client, object(), mark, "before the motion")
    assert client.sent == []


def test_a_halt_while_a_goal_is_sent_halts_the_robot_after_the_controller_has_the_goal() -> None:
    """The controller notes its halts when a goal arrives (sim/sim_node.py): the robot's halt must
    come after that, or a goal that crossed the halt could start after it."""
    calls: list[str] = []
    core = ServerCore(load_robot_configs()["ur10"], {}, {}, template_folder=None, state_file=None, instances={})
    switch = HaltSwitch(core, halt_client=RobotHaltClient(calls))
    client = TrajectoryClient()
    sending = switch.send_goal(client, object(), switch.mark(), "before the motion")
    handle = Accepted()

    def answer() -> None:
        calls.append("goal answered")
        sending.set_result(handle)

    timer = threading.Timer(0.2, answer)
    timer.start()
    try:
        response = _halt(switch)
    finally:
        timer.join()
    assert calls == ["goal answered", "robot halted"] and response.success
    assert handle.cancels == 1  # and the goal the halt waited for is cancelled


def test_a_goal_never_answered_does_not_keep_a_halt_waiting(switch: HaltSwitch) -> None:
    """The halt waits GOAL_ANSWER_WAIT_S for it, then halts (a wait for ever would hang this test)."""
    switch.send_goal(TrajectoryClient(), object(), switch.mark(), "before the motion")
    assert _halt(switch).success
