"""RecordedActionClient: an answer that arrives before its request is on record still settles it.

The interleaving that loses answers with rclpy's own ActionClient is forced here: the request
is sent, and the sending thread then waits until an executor thread has begun handling the
answer before it lets the client record the request.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy
from caretaker_sim_msgs.action import FollowJointTrajectory
from rclpy.action import ActionServer
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor

from at_ros.action_client import RecordedActionClient
from support.spinner import Spinner

ANSWER_WAIT = 5.0


class ProbedClient(RecordedActionClient):
    """Signals when an executor thread starts handling taken data."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.handling = threading.Event()

    async def execute(self, taken_data: dict[str, Any]) -> None:
        if "goal" in taken_data or "result" in taken_data:
            self.handling.set()
        await super().execute(taken_data)


class SendThenStall:
    """Stands in for the client's rcl handle: sends for real, then holds the sender until the
    answer is being handled on another thread (or ANSWER_WAIT passed)."""

    def __init__(self, handle: Any, handling: threading.Event) -> None:
        self._handle = handle
        self._handling = handling
        self.stalled = 0

    def _stall_after(self, sequence_number: int) -> int:
        self._handling.clear()
        if self._handling.wait(ANSWER_WAIT):
            self.stalled += 1
        return sequence_number

    def send_goal_request(self, request: Any) -> int:
        return self._stall_after(self._handle.send_goal_request(request))

    def send_result_request(self, request: Any) -> int:
        return self._stall_after(self._handle.send_result_request(request))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._handle, name)

    def __enter__(self) -> Any:
        return self._handle.__enter__()

    def __exit__(self, *exc: Any) -> None:
        self._handle.__exit__(*exc)


@pytest.fixture
def node_pair() -> Iterator[tuple[Any, Any, MultiThreadedExecutor]]:
    context = rclpy.Context()
    rclpy.init(context=context)
    server_node = rclpy.create_node("recorded_action_server", context=context)
    client_node = rclpy.create_node("recorded_action_client", context=context)
    executor = MultiThreadedExecutor(num_threads=4, context=context)
    executor.add_node(server_node)
    executor.add_node(client_node)
    spinner = Spinner(executor, server_node, name="action-pair")
    try:
        yield server_node, client_node, executor
    finally:
        spinner.stop()
        server_node.destroy_node()
        client_node.destroy_node()
        rclpy.shutdown(context=context)


def test_answers_taken_before_the_request_is_recorded_still_settle_it(
    node_pair: tuple[Any, Any, MultiThreadedExecutor],
) -> None:
    server_node, client_node, _ = node_pair
    name = "/recorded_action_test/follow"

    def execute(goal_handle: Any) -> Any:
        goal_handle.succeed()
        result = FollowJointTrajectory.Result()
        result.error_string = "done"
        return result

    ActionServer(
        server_node, FollowJointTrajectory, name, execute_callback=execute, callback_group=ReentrantCallbackGroup()
    )
    client = ProbedClient(client_node, FollowJointTrajectory, name, callback_group=ReentrantCallbackGroup())
    stall = SendThenStall(client._client_handle, client.handling)
    client._client_handle = stall
    assert client.wait_for_server(timeout_sec=20.0), "the action server was not discovered"

    for attempt in range(3):
        accepted = threading.Event()
        future = client.send_goal_async(FollowJointTrajectory.Goal())
        future.add_done_callback(lambda _, accepted=accepted: accepted.set())
        assert accepted.wait(ANSWER_WAIT + 5.0), f"goal {attempt}: its acceptance was lost"
        handle = future.result()
        assert handle.accepted
        finished = threading.Event()
        result = handle.get_result_async()
        result.add_done_callback(lambda _, finished=finished: finished.set())
        assert finished.wait(ANSWER_WAIT + 5.0), f"goal {attempt}: its result was lost"
        assert result.result().result.error_string == "done"
    assert stall.stalled >= 2, "the answers never overtook their requests: the race was not forced"
