"""Waiting for a trajectory goal's result: an answer lost on the way is asked for again, never the goal.

In-process, with rclpy futures and a stand-in for rclpy's ClientGoalHandle (the real action
client's bookkeeping is tests/at_ros/test_action_client.py; the whole execution, the real stacks).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
from rclpy.task import Future

from at_ros import plan_execute
from at_ros.plan_execute import trajectory_result
from at_ros.server_core import CommandRefused


class GoalHandle:
    """Stands in for an accepted goal's ClientGoalHandle: each get_result request gets the next
    of ``answers`` at once, or (None) no answer ever."""

    def __init__(self, answers: list[Any]) -> None:
        self.goal_id = SimpleNamespace(uuid=list(range(16)))
        self._answers = list(answers)
        self.requests: list[Future] = []

    def get_result_async(self) -> Future:
        future = Future()
        answer = self._answers.pop(0)
        if answer is not None:
            future.set_result(answer)
        self.requests.append(future)
        return future


@pytest.fixture(autouse=True)
def ask_again_soon(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(plan_execute, "RESULT_ASK_AGAIN_S", 0.05)


def test_a_result_whose_answer_was_lost_is_asked_for_again() -> None:
    handle = GoalHandle([None, "reached the goal"])
    assert trajectory_result(handle, timeout=60.0) == "reached the goal"
    first, second = handle.requests
    assert first.cancelled() and second.done() and not second.cancelled()


def test_a_result_that_never_comes_fails_the_motion_at_its_timeout() -> None:
    handle = GoalHandle([None] * 1000)
    with pytest.raises(CommandRefused, match=r"^the trajectory action did not answer within 0 s$"):
        trajectory_result(handle, timeout=0.2)
    assert handle.requests and all(request.cancelled() for request in handle.requests)
