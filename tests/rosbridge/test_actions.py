"""ROS 2 actions both ways through the real bridge (roslibpy sends goals; raw clients serve)."""

from __future__ import annotations

from collections.abc import Callable

import roslibpy
from roslibpy.core import GoalStatus

from .rosbridge_support import Inbox, RawClient

ACTION_TYPE = "caretaker_sim_msgs/action/FollowJointTrajectory"


def trajectory(points: int, tolerance: float = 0.01) -> dict:
    return {
        "trajectory": {"joint_names": ["a", "b"], "points": [{"positions": [0.1 * i, 0.2 * i]} for i in range(points)]},
        "goal_tolerance": tolerance,
    }


def test_goal_with_feedback_succeeds(connect: Callable[[], roslibpy.Ros]) -> None:
    client = roslibpy.ActionClient(connect(), "/peer/follow", ACTION_TYPE)
    results, feedback, errors = Inbox(), Inbox(), Inbox()
    goal_id = client.send_goal(roslibpy.Goal(trajectory(3)), results, feedback, errors)
    client.wait_goal(goal_id, timeout=30)
    assert errors.items == []
    result = results.wait_for(1)[0]
    assert result["status"] is GoalStatus.SUCCEEDED
    assert result["values"]["error_string"] == "followed 3 points"
    assert [f["desired"] for f in feedback.wait_for(3)] == [[0.0, 0.0], [0.1, 0.2], [0.2, 0.4]]


def test_cancelled_goal_reports_canceled(connect: Callable[[], roslibpy.Ros]) -> None:
    client = roslibpy.ActionClient(connect(), "/peer/follow", ACTION_TYPE)
    results, feedback, errors = Inbox(), Inbox(), Inbox()
    goal_id = client.send_goal(roslibpy.Goal(trajectory(50)), results, feedback, errors)
    feedback.wait_for(1)
    client.cancel_goal(goal_id)
    client.wait_goal(goal_id, timeout=30)
    assert errors.wait_for(1)[0]["status"] is GoalStatus.CANCELED
    assert len(feedback.items) < 50


def test_aborted_goal_and_missing_server_answer_result_false(bridge: tuple[str, int]) -> None:
    raw = RawClient(*bridge)
    try:
        aborted = raw.request(
            {
                "op": "send_action_goal",
                "id": "g1",
                "action": "/peer/follow",
                "action_type": ACTION_TYPE,
                "args": trajectory(1, tolerance=-1),
            },
            "action_result",
        )
        assert aborted["result"] is False and aborted["status"] == 6 and aborted["id"] == "g1"
        assert aborted["values"]["error_string"] == "negative tolerance"
        missing = raw.request(
            {"op": "send_action_goal", "id": "g2", "action": "/no/action", "action_type": ACTION_TYPE}, "action_result"
        )
        assert missing == {
            "op": "action_result",
            "action": "/no/action",
            "id": "g2",
            "status": 0,
            "result": False,
            "values": "Action server /no/action is not available",
        }
    finally:
        raw.close()


def test_client_serves_an_action_for_another_client(bridge: tuple[str, int]) -> None:
    server, caller = RawClient(*bridge), RawClient(*bridge)
    try:
        server.send({"op": "advertise_action", "action": "/bridge_test/move", "type": ACTION_TYPE})
        for attempt in range(100):  # the action server appears on the graph asynchronously
            caller.send(
                {
                    "op": "send_action_goal",
                    "id": f"try{attempt}",
                    "action": "/bridge_test/move",
                    "action_type": ACTION_TYPE,
                    "args": trajectory(2),
                    "feedback": True,
                }
            )
            try:
                request = server.receive_op("send_action_goal", timeout=0.3)
                break
            except TimeoutError:
                answer = caller.receive_op("action_result")
                assert "not available" in answer["values"]
        assert request["id"].startswith("action_goal:/bridge_test/move:")
        assert request["args"]["trajectory"]["joint_names"] == ["a", "b"] and request["feedback"] is True
        server.send(
            {
                "op": "action_feedback",
                "id": request["id"],
                "action": "/bridge_test/move",
                "values": {"desired": [1.0], "time_from_start": 0.5},
            }
        )
        feedback = caller.receive_op("action_feedback")
        assert feedback["values"]["desired"] == [1.0] and feedback["id"] == f"try{attempt}"
        server.send(
            {
                "op": "action_result",
                "id": request["id"],
                "action": "/bridge_test/move",
                "values": {"error_code": 0, "error_string": "done by a client"},
                "status": 4,
                "result": True,
            }
        )
        result = caller.receive_op("action_result")
        assert result["status"] == 4 and result["result"] is True
        assert result["values"] == {"error_code": 0, "error_string": "done by a client"}
    finally:
        server.close()
        caller.close()
