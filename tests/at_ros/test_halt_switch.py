"""HaltSwitch in-process: what a halt stops and says for a robot without a halt service, and how
a command learns of a halt (the real stack's halt is tests/at_ros/test_halt.py)."""

from __future__ import annotations

import pytest
from affordance_template_msgs.srv import Halt

from at_ros.halt import Halted, HaltSwitch
from at_ros.robot_config import load_robot_configs
from at_ros.server_core import ServerCore


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
