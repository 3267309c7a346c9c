"""Megabyte fields and action-server churn on a bridge with its default limits, and services
kept ready.

Names, types, ids and data of 1 MB and 9.9 MB (just under the 10 MB message limit) in every
operation that takes them, and clients serving or using actions that disconnect with goals in
flight, over and over: every call is answered within 10 s, a well-formed call after each attack
too, and the bridge logs no traceback (an action server destroyed under its executor's wait
once logged ``RCLError: ... action server pointer is invalid``; one destroyed before its result
was sent left the caller's goal unanswered).
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from support.processes import ManagedProcess, caretaker

from .hostile import BridgeLog
from .rosbridge_support import RawClient, bridge_url

pytestmark = [pytest.mark.ros, pytest.mark.slow]

ANSWER_WITHIN_S = 10.0
ACTION_TYPE = "caretaker_sim_msgs/action/FollowJointTrajectory"
GOAL = {"trajectory": {"joint_names": ["a"], "points": [{"positions": [0.1]}]}, "goal_tolerance": 0.01}
SIZES = (1_000_000, 9_900_000)


@pytest.fixture(scope="module")
def logged_bridge(ros_env: dict[str, str]) -> Iterator[tuple[ManagedProcess, BridgeLog, tuple[str, int]]]:
    """A bridge with the default limits, its log read line by line: (process, log, address)."""
    log = BridgeLog()
    process = caretaker("bridge", "--port", "0", env=ros_env, on_line=log)
    try:
        process.wait_ready(60)
        host, port = bridge_url(process).split("//")[1].rsplit(":", 1)
        yield process, log, (host, int(port))
    finally:
        process.stop()


def _requests(size: int) -> list[dict]:
    big = "x" * (size - 200)  # the rest of the message fits in what is left of the limit
    return [
        {"op": "call_service", "service": "/" + big, "id": "call with a long name"},
        {"op": "call_service", "service": "/rosapi/get_ros_version", "id": big},
        {"op": "call_service", "service": "/rosapi/get_ros_version", "type": big, "id": "call with a long type"},
        {
            "op": "call_service",
            "service": "/rosapi/get_ros_version",
            "args": {"data": big},
            "id": "call with long data",
        },
        {"op": "subscribe", "topic": "/" + big, "type": "std_msgs/msg/String", "id": "subscribe"},
        {"op": "advertise", "topic": "/" + big, "type": "std_msgs/msg/String", "id": "advertise"},
        {"op": "advertise", "topic": "/large/topic", "type": big, "id": "advertise a long type"},
        {"op": "publish", "topic": "/large/topic", "msg": {"data": big}, "id": "publish"},
        {"op": "send_action_goal", "action": "/" + big, "action_type": ACTION_TYPE, "args": GOAL, "id": "goal"},
        {"op": big, "id": "unknown op"},
    ]


def _answered_in_time(client: RawClient, wanted: list[str]) -> list[str]:
    """Read answers (service_response, action_result) until every id in ``wanted`` has one; the ids
    not answered within :data:`ANSWER_WITHIN_S` of the last answer are returned."""
    left = list(wanted)
    while left:
        try:
            message = client.receive(timeout=ANSWER_WITHIN_S)
        except TimeoutError:
            break
        if message.get("op") in ("service_response", "action_result") and message.get("id") in left:
            left.remove(message["id"])
    return left


@pytest.mark.parametrize("size", SIZES, ids=["1MB", "9.9MB"])
def test_megabyte_names_types_ids_and_data_are_answered(
    logged_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]], size: int
) -> None:
    process, log, address = logged_bridge
    tracebacks = log.snapshot()[1]
    client = RawClient(*address, max_size=None)
    try:
        for request in _requests(size):
            started = time.monotonic()
            client.send(request)
            must_answer = [request["id"]] if request["op"] in ("call_service", "send_action_goal") else []
            client.send({"op": "call_service", "service": "/rosapi/get_ros_version", "id": "after"})
            assert not _answered_in_time(client, [*must_answer, "after"]), (
                f"{request['op']} with a {size}-byte field: not answered within {ANSWER_WITHIN_S} s"
            )
            print(
                f"{size} B, {str(request['op'])[:20]} ({str(request['id'])[:24]}): "
                f"answered in {time.monotonic() - started:.2f} s"
            )
    finally:
        client.close()
    assert process.running
    assert log.snapshot()[1] == tracebacks, f"the bridge logged a traceback:\n{process.tail()}"


def _in_order(client: RawClient) -> None:
    """Return once the bridge has handled everything ``client`` sent before (it handles a
    client's messages in order)."""
    client.request(
        {"op": "call_service", "service": "/rosapi/get_ros_version", "id": "in order"},
        "service_response",
        timeout=ANSWER_WITHIN_S,
    )


def _wait_listed(client: RawClient, action: str) -> None:
    """Return once the bridge's graph lists the action's goal service (discovery is asynchronous)."""
    wanted = f"{action}/_action/send_goal"
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        listed = client.request(
            {"op": "call_service", "service": "/rosapi/services", "id": "listed"},
            "service_response",
            timeout=ANSWER_WITHIN_S,
        )["values"]["services"]
        if wanted in listed:
            return
    pytest.fail(f"{wanted} was not listed within 30 s")


def test_clients_leaving_with_goals_in_flight_under_action_server_churn(
    logged_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]],
) -> None:
    process, log, address = logged_bridge
    tracebacks = log.snapshot()[1]
    for round_ in range(8):
        # The same two names again and again: each advertisement takes over a withdrawn server
        # (or a new one) while late answers of the previous round may still be on their way.
        action = f"/churn/move_{round_ % 2}"
        server, caller = RawClient(*address), RawClient(*address)
        server.send({"op": "advertise_action", "action": action, "type": ACTION_TYPE})
        _in_order(server)
        _wait_listed(caller, action)
        caller.send(
            {"op": "send_action_goal", "id": "goal", "action": action, "action_type": ACTION_TYPE, "args": GOAL}
        )
        server.receive_op("send_action_goal", timeout=ANSWER_WITHIN_S)
        if round_ % 2:  # the serving client leaves first: the goal is aborted and answered
            server.close()
            assert caller.receive_op("action_result", timeout=ANSWER_WITHIN_S)["result"] is False
            # A goal after its server's client left is answered too (refused or aborted).
            caller.send(
                {
                    "op": "send_action_goal",
                    "id": "late goal",
                    "action": action,
                    "action_type": ACTION_TYPE,
                    "args": GOAL,
                }
            )
            assert caller.receive_op("action_result", timeout=ANSWER_WITHIN_S)["result"] is False
            caller.close()
        else:  # the caller leaves: its goal is cancelled, then its server goes too
            caller.close()
            server.receive_op("cancel_action_goal", timeout=ANSWER_WITHIN_S)
            server.close()
    probe = RawClient(*address)
    try:
        _in_order(probe)
    finally:
        probe.close()
    assert process.running
    assert log.snapshot()[1] == tracebacks, f"the bridge logged a traceback:\n{process.tail()}"


def test_ready_services_have_a_matched_client_before_their_first_call(ros_env: dict[str, str]) -> None:
    """``--ready-services GLOB``: the bridge makes the client of a matching service as soon as the
    graph shows it (a halt's first call must not wait for discovery), and of no other. The
    services are this test's own, so no other bridge of the session has clients of them."""
    import rclpy
    from std_srvs.srv import Trigger

    context = rclpy.Context()  # this test's own: other tests in this process may use rclpy's default
    rclpy.init(context=context, domain_id=int(ros_env["ROS_DOMAIN_ID"]))
    process = None
    try:
        node = rclpy.create_node("ready_services_probe", context=context)
        try:
            for name in ("/ready_probe/halt", "/ready_probe/other"):
                node.create_service(Trigger, name, lambda request, response: response)
            process = caretaker("bridge", "--port", "0", "--ready-services", "/ready_probe/h*", env=ros_env)
            process.wait_ready(60)
            deadline = time.monotonic() + 30.0
            while node.count_clients("/ready_probe/halt") == 0 and time.monotonic() < deadline:
                time.sleep(0.05)  # rclpy offers no graph event to await
            assert node.count_clients("/ready_probe/halt") == 1, "no client made without a call"
            assert node.count_clients("/ready_probe/other") == 0
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
        if process is not None:
            process.stop()
