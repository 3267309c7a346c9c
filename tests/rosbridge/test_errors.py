"""Every failed request is answered and the connection stays up (raw JSON frames)."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

from .rosbridge_support import RawClient


@pytest.fixture
def raw(bridge: tuple[str, int]) -> Iterator[RawClient]:
    client = RawClient(*bridge)
    client.send({"op": "set_level", "level": "error"})
    yield client
    client.close()


def test_malformed_json_is_answered_and_the_connection_survives(raw: RawClient) -> None:
    raw.send("{not json")
    status = raw.receive_op("status")
    assert status["level"] == "error" and "invalid JSON" in status["msg"]
    answer = raw.request({"op": "call_service", "service": "/rosapi/get_ros_version", "id": 1}, "service_response")
    assert answer == {
        "op": "service_response",
        "service": "/rosapi/get_ros_version",
        "id": 1,
        "values": {"version": 2, "distro": "jazzy"},
        "result": True,
    }


@pytest.mark.parametrize(
    "message, expected",
    [
        ({"op": "teleport", "id": "t1"}, "unknown op 'teleport'"),
        ({"id": "t2"}, "needs a string field 'op'"),
        ({"op": "subscribe", "id": "t3"}, "missing field 'topic'"),
        ({"op": "subscribe", "id": "t4", "topic": "/x", "type": "no_pkg/Thing"}, "unknown msg type 'no_pkg/Thing'"),
        ({"op": "subscribe", "id": "t5", "topic": "/never/seen"}, "does not exist yet: give its type"),
        (
            {"op": "subscribe", "id": "t6", "topic": "/x", "type": "std_msgs/String", "queue_length": "many"},
            "field 'queue_length' must be an integer",
        ),
        (
            {"op": "publish", "id": "t7", "topic": "/bridge_test/bad", "type": "std_msgs/String", "msg": {"data": 5}},
            "msg.data: expected a string, got int 5",
        ),
        (
            {
                "op": "publish",
                "id": "t8",
                "topic": "/bridge_test/bad2",
                "type": "std_msgs/String",
                "msg": {"text": "a"},
            },
            "has no field 'text'",
        ),
        ({"op": "unsubscribe", "id": "t9", "topic": "/not/subscribed"}, "no subscription to /not/subscribed"),
        (
            {"op": "advertise", "id": "t10", "topic": "/peer/echo_in", "type": "std_msgs/Int32"},
            "already has type std_msgs/msg/String",
        ),
    ],
)
def test_bad_requests_get_a_status_naming_op_id_and_reason(raw: RawClient, message: dict, expected: str) -> None:
    status = raw.request(message, "status")
    assert status["level"] == "error"
    assert status.get("id") == message["id"]
    assert expected in status["msg"]
    if "op" in message:
        assert status["msg"].startswith(f"{message['op']} {message['id']}")


def test_failed_service_calls_answer_with_result_false_and_the_id(raw: RawClient) -> None:
    answer = raw.request({"op": "call_service", "service": "/nope", "id": "call:1"}, "service_response")
    assert answer == {
        "op": "service_response",
        "service": "/nope",
        "values": "Service /nope does not exist",
        "result": False,
        "id": "call:1",
    }
    answer = raw.request(
        {"op": "call_service", "service": "/peer/set_bool", "id": 7, "args": {"data": "yes"}}, "service_response"
    )
    assert answer["result"] is False and answer["id"] == 7 and "args.data: expected true or false" in answer["values"]
    answer = raw.request({"op": "call_service", "service": "/peer/slow", "id": "t", "timeout": 0.3}, "service_response")
    assert answer == {
        "op": "service_response",
        "service": "/peer/slow",
        "result": False,
        "id": "t",
        "values": "Timeout exceeded while waiting for service response",
    }


def test_list_args_are_taken_in_field_order(raw: RawClient) -> None:
    answer = raw.request({"op": "call_service", "service": "/peer/set_bool", "args": [True]}, "service_response")
    assert answer["values"] == {"success": True, "message": "got true"}


def test_without_set_level_no_status_is_sent(bridge: tuple[str, int]) -> None:
    client = RawClient(*bridge)
    try:
        client.send({"op": "teleport"})
        answer = client.request({"op": "call_service", "service": "/rosapi/get_ros_version"}, "service_response")
        assert answer["result"] is True
    finally:
        client.close()


def test_fragmented_request_is_reassembled(raw: RawClient) -> None:
    text = '{"op":"call_service","service":"/peer/set_bool","id":"frag","args":{"data":true}}'
    parts = [text[i : i + 10] for i in range(0, len(text), 10)]
    for num, part in enumerate(parts):
        raw.send({"op": "fragment", "id": "f1", "data": part, "num": num, "total": len(parts)})
    answer = raw.receive_op("service_response")
    assert answer["id"] == "frag" and answer["values"]["success"] is True


def test_websocket_fragmented_message_keeps_its_place_in_order(raw: RawClient) -> None:
    # One message in three WebSocket frames, then one in a single frame (which the bridge can
    # handle as soon as it is parsed): both are answered in the order they were sent.
    text = json.dumps({"op": "teleport", "id": "first"})
    raw.connection.send([text[:7], text[7:15], text[15:]])
    raw.send({"op": "teleport", "id": "second"})
    raw.send({"op": "teleport", "id": "third"})
    assert [raw.receive_op("status")["id"] for _ in range(3)] == ["first", "second", "third"]


def test_subscription_with_fragment_size_sends_fragments(raw: RawClient) -> None:
    topic, text = "/bridge_test/fragmented", "x" * 3000
    raw.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String", "fragment_size": 1024, "id": "s1"})
    for _ in range(100):  # ROS matches the bridge's new publisher to its subscription asynchronously
        raw.send({"op": "publish", "topic": topic, "type": "std_msgs/String", "msg": {"data": text}})
        try:
            fragments = [raw.receive_op("fragment", timeout=0.2)]
            break
        except TimeoutError:
            continue
    while len(fragments) < fragments[0]["total"]:
        fragments.append(raw.receive_op("fragment"))
    assert [f["num"] for f in fragments] == list(range(fragments[0]["total"])) and len(fragments) == 3
    assert all(len(f["data"]) <= 1024 for f in fragments)
    whole = json.loads("".join(f["data"] for f in fragments))
    assert whole == {"op": "publish", "topic": topic, "msg": {"data": text}}
