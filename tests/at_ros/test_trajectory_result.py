"""Waiting for a trajectory goal's result: an answer lost on the way is asked for again, never the
goal; a goal with no result in time is cancelled, and the answer says what became of it.

In-process, with rclpy futures and a stand-in for rclpy's ClientGoalHandle (the real action
client's bookkeeping is tests/at_ros/test_action_client.py; the whole execution, the real stacks).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from caretaker_sim_msgs.action import FollowJointTrajectory
from rclpy.task import Future

from at_ros import plan_execute
from at_ros.plan_execute import reached, trajectory_result
from at_ros.server_core import CommandRefused

REACHED = SimpleNamespace(
    status=GoalStatus.STATUS_SUCCEEDED,
    result=SimpleNamespace(error_code=FollowJointTrajectory.Goal.SUCCESSFUL, error_string=""),
)
NOTHING_MOVED = SimpleNamespace(
    status=GoalStatus.STATUS_CANCELED,
    result=SimpleNamespace(error_code=-7, error_string="cancelled before it started: nothing moved"),
)
#: How ros2_controllers' controller ends a goal cancelled mid-motion: code SUCCESSFUL, status CANCELED.
STOPPED_SHORT = SimpleNamespace(
    status=GoalStatus.STATUS_CANCELED,
    result=SimpleNamespace(error_code=FollowJointTrajectory.Goal.SUCCESSFUL, error_string=""),
)


class GoalHandle:
    """Stands in for an accepted goal's ClientGoalHandle: each get_result request gets the next
    of ``answers`` at once, or (None) no answer ever; once cancelled, the next of ``after_cancel``."""

    def __init__(self, answers: list[Any], after_cancel: list[Any] | None = None) -> None:
        self.goal_id = SimpleNamespace(uuid=list(range(16)))
        self._answers = list(answers)
        self._after_cancel = after_cancel
        self.cancelled = False
        self.requests: list[Future] = []

    def get_result_async(self) -> Future:
        future = Future()
        answers = self._after_cancel if self.cancelled and self._after_cancel is not None else self._answers
        answer = answers.pop(0)
        if answer is not None:
            future.set_result(answer)
        self.requests.append(future)
        return future

    def cancel_goal_async(self) -> Future:
        self.cancelled = True
        return Future()


@pytest.fixture(autouse=True)
def ask_again_soon(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(plan_execute, "RESULT_ASK_AGAIN_S", 0.05)
    monkeypatch.setattr(plan_execute, "CANCEL_WAIT_S", 0.2)


def test_a_result_whose_answer_was_lost_is_asked_for_again() -> None:
    handle = GoalHandle([None, REACHED])
    assert trajectory_result(handle, timeout=60.0) is REACHED
    first, second = handle.requests
    assert first.cancelled() and second.done() and not second.cancelled()
    assert not handle.cancelled


def test_a_goal_with_no_result_in_time_is_cancelled_and_its_answer_says_nothing_moved() -> None:
    handle = GoalHandle([None] * 1000, after_cancel=[NOTHING_MOVED])
    with pytest.raises(
        CommandRefused,
        match=r"^the trajectory action gave no result within 0 s, so its goal was "
        r"cancelled: cancelled before it started: nothing moved$",
    ):
        trajectory_result(handle, timeout=0.2)
    assert handle.cancelled


def test_a_goal_that_finished_as_it_was_cancelled_is_a_success() -> None:
    handle = GoalHandle([None] * 1000, after_cancel=[REACHED])
    assert trajectory_result(handle, timeout=0.2) is REACHED
    assert handle.cancelled


def test_a_goal_that_never_answers_even_once_cancelled_is_not_known_to_have_stopped() -> None:
    handle = GoalHandle([None] * 1000)
    with pytest.raises(
        CommandRefused,
        match=r"^the trajectory action did not answer within 0 s, nor 0 s after its "
        r"goal was cancelled: whether the arm moves is not known; halt it and check$",
    ):
        trajectory_result(handle, timeout=0.2)
    assert handle.cancelled
    assert handle.requests and all(request.cancelled() for request in handle.requests)


def test_a_goal_cancelled_mid_motion_is_never_a_success_whatever_its_code() -> None:
    assert not reached(STOPPED_SHORT) and reached(REACHED)
    handle = GoalHandle([None] * 1000, after_cancel=[STOPPED_SHORT])
    with pytest.raises(
        CommandRefused, match=r"goal was cancelled: cancelled \(error code 0\): the arm stopped short of the waypoint$"
    ):
        trajectory_result(handle, timeout=0.3)
