"""Issue 20's defects, each with its minimal reproducer, against a bridge with small quotas.

Every test runs under the ``watch`` fixture: a well-formed client keeps calling the bridge
during the attack, and afterwards the bridge's own work while one call waited must stay under
2 s of CPU (hostile.py's ``STALL_BOUND_S``), the bridge's RSS growth under 200 MiB, and the
bridge must have logged no traceback (conftest.py).
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator

import pytest

from support.processes import ManagedProcess

from .hostile import READ_PAUSE_BYTES, SOURCE_PATH, BridgeLog, Watch
from .rosbridge_support import PING, FrameSocket, RawClient, frame, text

MiB = 2**20
#: What the bridge's RSS may grow by beyond the read-pause bound while a client floods pings: the
#: allocator's arenas and the watching client's own calls (an unbounded bridge grew by 17-46 MiB).
PING_SLACK = 4 * MiB
ACTION_TYPE = "caretaker_sim_msgs/action/FollowJointTrajectory"


@pytest.fixture
def address(hostile_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]]) -> tuple[str, int]:
    return hostile_bridge[2]


@pytest.fixture
def client(address: tuple[str, int]) -> Iterator[RawClient]:
    raw = RawClient(*address)
    raw.send({"op": "set_level", "level": "error"})
    yield raw
    raw.close()


def status_of(client: RawClient, message: dict | str) -> str:
    """The error status the bridge answers ``message`` with (its text, checked for source paths)."""
    client.send(message)
    status = client.receive_op("status")
    assert not SOURCE_PATH.search(status["msg"]), status
    return status["msg"]


def until_received(publisher: RawClient, subscriber: RawClient, publish: dict, timeout: float = 20.0) -> dict:
    """Publish until the subscriber gets a message (ROS matches publishers asynchronously)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        publisher.send(publish)
        try:
            return subscriber.receive_op("publish", timeout=0.2)
        except TimeoutError:
            continue
    raise AssertionError(f"nothing arrived on {publish['topic']}")


# --- 1. out-of-range integers ------------------------------------------------------------------


@pytest.mark.parametrize(
    "type_, warm, bad, good, expected",
    [
        (
            "std_msgs/msg/Int8",
            {"data": 1},
            {"data": 128},
            {"data": 5},
            "msg.data: int 128 is out of the range of int8 (-128 to 127)",
        ),
        (
            "std_msgs/msg/UInt32",
            {"data": 1},
            {"data": 2**32},
            {"data": 7},
            "out of the range of uint32 (0 to 4294967295)",
        ),
        (
            "std_msgs/msg/UInt32",
            {"data": 1},
            {"data": -1},
            {"data": 8},
            "msg.data: int -1 is out of the range of uint32",
        ),
        (
            "std_msgs/msg/Header",
            {"stamp": {"sec": 1}},
            {"stamp": {"sec": 2**31}},
            {"stamp": {"sec": 9}},
            "msg.stamp.sec: int 2147483648 is out of the range of int32",
        ),
        ("std_msgs/msg/Float32", {"data": 0.5}, {"data": 1e39}, {"data": 1.5}, "out of the range of float32"),
    ],
)
def test_out_of_range_values_are_refused_and_never_published(
    watch: Watch,
    client: RawClient,
    address: tuple[str, int],
    type_: str,
    warm: dict,
    bad: dict,
    good: dict,
    expected: str,
) -> None:
    topic = f"/hostile/range_{type_.rsplit('/', 1)[1].lower()}"
    subscriber = RawClient(*address)
    try:
        subscriber.send({"op": "subscribe", "topic": topic, "type": type_})
        until_received(client, subscriber, {"op": "publish", "topic": topic, "type": type_, "msg": warm})
        assert expected in status_of(client, {"op": "publish", "topic": topic, "type": type_, "msg": bad, "id": "bad"})
        client.send({"op": "publish", "topic": topic, "type": type_, "msg": good})
        warm_message = _full(type_, warm)
        received = subscriber.receive_op("publish")["msg"]
        while received == warm_message:  # copies of the warm-up may still be on their way
            received = subscriber.receive_op("publish")["msg"]
        assert received == _full(type_, good), "the refused value arrived"
    finally:
        subscriber.close()


def _full(type_: str, fields: dict) -> dict:
    if type_.endswith("Header"):
        return {"frame_id": "", "stamp": {"nanosec": 0, **fields["stamp"]}}
    return fields


# --- 2. goals of a client that disconnects ----------------------------------------------------


@pytest.mark.parametrize("when", ["before acceptance", "while executing"])
def test_goals_of_a_client_that_disconnects_are_cancelled(watch: Watch, address: tuple[str, int], when: str) -> None:
    observer = RawClient(*address)
    try:
        observer.send(
            {"op": "subscribe", "topic": "/peer/follow/_action/status", "type": "action_msgs/GoalStatusArray"}
        )
        try:  # the goals the action server still reports (its status topic is latched)
            earlier = {_uuid(s) for s in observer.receive_op("publish", timeout=2)["msg"]["status_list"]}
        except TimeoutError:
            earlier = set()
        goal = {
            "op": "send_action_goal",
            "id": "orphan",
            "action": "/peer/follow",
            "action_type": ACTION_TYPE,
            "feedback": True,
            "args": {"trajectory": {"joint_names": ["a"], "points": [{"positions": [0.0]}] * 50}},
        }
        leaver = FrameSocket(*address)
        leaver.sock.sendall(text(goal))
        if when == "while executing":
            assert leaver.read_message()["op"] == "action_feedback"
        leaver.sock.close()  # gone without a word: the 50-point goal would run for 10 s
        deadline = time.monotonic() + 20
        ours: list[dict] = []
        while not any(s["status"] == 5 for s in ours):  # CANCELED
            assert time.monotonic() < deadline, f"the orphaned goal was not cancelled: {ours}"
            statuses = observer.receive_op("publish")["msg"]["status_list"]
            ours = [s for s in statuses if _uuid(s) not in earlier]
        assert len(ours) == 1
    finally:
        observer.close()


def _uuid(status: dict) -> str:
    return str(status["goal_info"]["goal_id"]["uuid"])


# --- 3. fragments and the size limit -----------------------------------------------------------


def test_fragments_cannot_exceed_the_size_limit(watch: Watch, client: RawClient) -> None:
    smuggled = json.dumps(
        {"op": "call_service", "service": "/rosapi/get_ros_version", "id": "smuggled", "pad": "x" * 1_200_000}
    )
    half = len(smuggled) // 2
    client.send({"op": "fragment", "id": "f", "num": 0, "total": 2, "data": "{"})
    client.send({"op": "fragment", "id": "f", "num": 0, "total": 2, "data": smuggled[:half]})  # replaces the first
    assert "exceeds 1000000 bytes" in status_of(
        client, {"op": "fragment", "id": "f", "num": 1, "total": 2, "data": smuggled[half:]}
    )
    answer = client.request(
        {"op": "call_service", "service": "/rosapi/get_ros_version", "id": "after"}, "service_response"
    )
    assert answer["id"] == "after", "the oversized message was executed"


def test_pending_fragmented_messages_are_limited_per_connection(watch: Watch, client: RawClient) -> None:
    for number in range(4):
        client.send({"op": "fragment", "id": f"part{number}", "num": 0, "total": 2, "data": "{}"})
    assert "(limit 4, --max-pending-fragments)" in status_of(
        client, {"op": "fragment", "id": "part4", "num": 0, "total": 2, "data": "{}"}
    )


# --- 4. amplification ----------------------------------------------------------------------------


def test_fragment_size_below_the_minimum_is_refused(watch: Watch, client: RawClient) -> None:
    answer = client.request(
        {"op": "call_service", "service": "/rosapi/services", "fragment_size": 1, "id": "tiny"}, "service_response"
    )
    assert answer["result"] is False and "'fragment_size' must be between 1024" in answer["values"]


def test_a_client_that_does_not_read_its_answers_costs_the_others_nothing(
    watch: Watch, address: tuple[str, int]
) -> None:
    greedy = FrameSocket(*address)
    greedy.sock.settimeout(0.5)  # the bridge stops reading it: sends then block
    call = text({"op": "call_service", "service": "/rosapi/services", "fragment_size": 1024})
    try:
        for _ in range(3000):
            greedy.sock.sendall(call)
    except TimeoutError:
        pass  # backpressure reached the client
    finally:
        greedy.close()


def test_subscribers_that_do_not_read_lose_old_messages_and_the_largest_is_cut_off(
    watch: Watch, address: tuple[str, int]
) -> None:
    publisher = RawClient(*address)
    readers = [FrameSocket(*address) for _ in range(5)]
    try:
        for index, reader in enumerate(readers):
            for copy in range(4):
                reader.sock.sendall(
                    text(
                        {
                            "op": "subscribe",
                            "topic": "/hostile/flood",
                            "type": "std_msgs/String",
                            "id": f"{index}.{copy}",
                            "fragment_size": 1024,
                        }
                    )
                )
        probe = RawClient(*address)
        try:
            probe.send({"op": "subscribe", "topic": "/hostile/flood", "type": "std_msgs/String"})
            until_received(
                publisher,
                probe,
                {"op": "publish", "topic": "/hostile/flood", "type": "std_msgs/String", "msg": {"data": "warm-up"}},
            )
        finally:
            probe.close()
        for index in range(40):
            publisher.send(
                {"op": "publish", "topic": "/hostile/flood", "msg": {"data": f"{index:04d}" + "y" * 500_000}}
            )
        publisher.request({"op": "call_service", "service": "/rosapi/get_time"}, "service_response")
        codes = []
        for reader in readers:  # 4 MiB each would be more than the bridge's 16 MiB in total
            reader.sock.settimeout(3)
            try:
                codes.append(reader.close_code())
            except (TimeoutError, ConnectionError):
                codes.append(None)
        assert 1008 in codes and codes.count(1008) < len(readers), codes
    finally:
        publisher.close()
        for reader in readers:
            reader.close()


# --- 5. subscriptions, advertisements, calls, goals, connections --------------------------------


def test_subscriptions_are_limited_and_new_connections_still_work(
    watch: Watch, client: RawClient, address: tuple[str, int]
) -> None:
    for number in range(20):
        client.send({"op": "subscribe", "topic": f"/hostile/many_{number}", "type": "std_msgs/String"})
    assert "too many subscriptions on this connection (limit 20, --max-subscriptions)" in status_of(
        client, {"op": "subscribe", "topic": "/hostile/many_20", "type": "std_msgs/String"}
    )
    newcomer = RawClient(*address)
    try:
        assert newcomer.request({"op": "call_service", "service": "/rosapi/get_time"}, "service_response")["result"]
    finally:
        newcomer.close()


def test_advertisements_are_limited(watch: Watch, client: RawClient) -> None:
    for number in range(10):
        client.send({"op": "advertise", "topic": f"/hostile/adv_{number}", "type": "std_msgs/String"})
    assert "(limit 10, --max-advertisements)" in status_of(
        client, {"op": "advertise_service", "service": "/hostile/adv_srv", "type": "std_srvs/Trigger"}
    )


def test_calls_in_flight_are_limited(watch: Watch, client: RawClient) -> None:
    for number in range(9):
        client.send({"op": "call_service", "service": "/peer/slow", "id": f"slow {number}", "timeout": 5})
    refused = client.receive_op("service_response")
    assert refused["id"] == "slow 8" and "(limit 8, --max-calls)" in refused["values"]
    answers = [client.receive_op("service_response") for _ in range(8)]
    assert all(answer["result"] for answer in answers)


def test_goals_in_flight_are_limited(watch: Watch, client: RawClient) -> None:
    goal = {
        "op": "send_action_goal",
        "action": "/peer/follow",
        "action_type": ACTION_TYPE,
        "args": {"trajectory": {"joint_names": ["a"], "points": [{"positions": [0.0]}] * 3}},
    }
    for number in range(5):
        client.send({**goal, "id": f"goal {number}"})
    refused = client.receive_op("action_result")
    assert refused["id"] == "goal 4" and "(limit 4, --max-goals)" in refused["values"]
    assert all(client.receive_op("action_result")["result"] for _ in range(4))


def test_connections_beyond_the_limit_are_refused_with_503(watch: Watch, address: tuple[str, int]) -> None:
    from websockets.exceptions import InvalidStatus

    clients: list[RawClient] = []
    try:
        with pytest.raises(InvalidStatus) as refused:
            for _ in range(16):
                clients.append(RawClient(*address))
        assert refused.value.response.status_code == 503 and len(clients) <= 15  # the watch holds one
    finally:
        for client in clients:
            client.close()


# --- 6. action clients ---------------------------------------------------------------------------


def test_goals_to_actions_nobody_offers_leave_no_action_client(watch: Watch, client: RawClient) -> None:
    for batch in range(3):
        for number in range(4):
            client.send(
                {
                    "op": "send_action_goal",
                    "action": f"/hostile/nothing_{batch}_{number}",
                    "action_type": ACTION_TYPE,
                    "id": f"{batch}.{number}",
                }
            )
        for _ in range(4):
            assert "is not available" in client.receive_op("action_result")["values"]
    topics = client.request({"op": "call_service", "service": "/rosapi/topics"}, "service_response")["values"]
    assert not [t for t in topics["topics"] if t.startswith("/hostile/nothing_")]


# --- 7. pings and log volume ---------------------------------------------------------------------


def test_pings_a_client_never_reads_are_not_buffered_without_end(watch: Watch, address: tuple[str, int]) -> None:
    pinger = FrameSocket(*address)
    pinger.sock.settimeout(0.5)
    ping = frame(PING, b"p" * 125)
    try:
        for _ in range(200_000):  # 26 MB of pings, unless the bridge stops reading first
            pinger.sock.sendall(ping)
    except TimeoutError:
        pass
    finally:
        # the pongs it does not take stop the bridge reading its pings: the kernel's buffers, not
        # the bridge's memory, hold the rest (checked with the pinger still connected)
        watch.check(rss_growth=READ_PAUSE_BYTES + PING_SLACK)
        pinger.close()


def test_bad_requests_do_not_grow_the_log_without_end(
    watch: Watch, hostile_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]], client: RawClient
) -> None:
    lines_before = hostile_bridge[1].snapshot()[0]
    for number in range(3000):
        client.send(f'{{"op":"teleport","id":{number},"pad":"{"z" * 2000}"}}')
    assert client.request({"op": "call_service", "service": "/rosapi/get_time"}, "service_response")["result"]
    assert hostile_bridge[1].snapshot()[0] - lines_before < 60


# --- 8. values the bridge echoes -----------------------------------------------------------------


@pytest.mark.parametrize(
    "frame_text, expected",
    [
        (
            '{"op":"call_service","service":"/rosapi/topics","id":NaN}',
            {"op": "service_response", "service": "/rosapi/topics", "result": False},
        ),
        ('{"op":"call_service","service":Infinity,"id":"x"}', {"op": "service_response", "id": "x", "result": False}),
        ('{"op":"call_service","service":"/rosapi/topics","id":%s}' % ("1" * 4400), {"op": "status"}),
        (
            '{"op":"call_service","service":"/a\\ud800","id":"\\udc00"}',
            {"op": "service_response", "id": "\\udc00", "result": False},
        ),
        (
            f'{{"op":"send_action_goal","action":"/peer/follow","action_type":"{ACTION_TYPE}","id":1e400}}',
            {"op": "action_result", "result": False},
        ),
        ('{"op":"publish","topic":"/hostile/s","type":"std_msgs/String","msg":{"data":"\\ud800"}}', {"op": "status"}),
        ('{"op":"advertise","topic":"/hostile/1bad","type":"std_msgs/String","id":-Infinity}', {"op": "status"}),
    ],
)
def test_hostile_values_in_echoed_fields_are_answered(
    watch: Watch, client: RawClient, frame_text: str, expected: dict
) -> None:
    client.send(frame_text)
    answer = client.receive_op(expected["op"])
    assert {k: answer.get(k) for k in expected} == expected
    reason = answer.get("values") or answer.get("msg")
    assert isinstance(reason, str) and reason and not SOURCE_PATH.search(reason)


def test_a_subscribe_refused_halfway_leaves_no_ros_subscription(
    watch: Watch, client: RawClient, address: tuple[str, int]
) -> None:
    topic = "/hostile/throttled"
    assert "'throttle_rate' must be between" in status_of(
        client, f'{{"op":"subscribe","topic":"{topic}","type":"std_msgs/String","throttle_rate":{"9" * 400}}}'
    )
    topics = client.request({"op": "call_service", "service": "/rosapi/topics"}, "service_response")["values"]
    assert topic not in topics["topics"]
    subscriber = RawClient(*address)
    try:
        subscriber.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
        assert until_received(
            client, subscriber, {"op": "publish", "topic": topic, "type": "std_msgs/String", "msg": {"data": "heard"}}
        )["msg"] == {"data": "heard"}
    finally:
        subscriber.close()


# --- 10. type names ------------------------------------------------------------------------------


def test_a_type_name_never_imports_a_module_that_is_no_interface_package(
    watch: Watch, hostile_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]], client: RawClient
) -> None:
    assert "no ROS interface package 'this' is installed" in status_of(
        client, {"op": "publish", "topic": "/hostile/zen", "type": "this/msg/Zen", "msg": {}}
    )
    assert "no ROS interface package 'os'" in status_of(
        client, {"op": "subscribe", "topic": "/hostile/os", "type": "os/msg/System"}
    )
    assert not hostile_bridge[1].forbidden


@pytest.mark.parametrize("name", ["/a//b", "/1a", "/a/", "/ä", "/a b", "/" + "n" * 300, "/~/x"])
def test_invalid_ros_names_are_answered(watch: Watch, client: RawClient, name: str) -> None:
    reason = status_of(client, {"op": "subscribe", "topic": name, "type": "std_msgs/String"})
    assert "not a valid ROS name" in reason or "too long for ROS" in reason


# --- issue 15: bytes per connection --------------------------------------------------------------


def test_bytes_each_way_are_counted_per_connection(watch: Watch, client: RawClient) -> None:
    client.send({"op": "publish", "topic": "/hostile/count", "type": "std_msgs/String", "msg": {"data": "c" * 5000}})
    first = client.request({"op": "call_service", "service": "/rosbridge/connection_stats"}, "service_response")
    values = first["values"]
    assert values["bytes_received"] > 5000 and values["messages_received"] == 3  # set_level, publish, this call
    assert values["bytes_sent"] > 0 and values["connected_s"] >= 0
    second = client.request({"op": "call_service", "service": "/rosbridge/connection_stats"}, "service_response")
    assert second["values"]["bytes_sent"] >= values["bytes_sent"] + len(json.dumps(first, separators=(",", ":"))) - 10


def test_a_request_its_serving_client_fails_or_abandons_logs_no_traceback(
    watch: Watch, address: tuple[str, int]
) -> None:
    server, caller = RawClient(*address), RawClient(*address)
    try:
        server.send({"op": "advertise_service", "service": "/hostile/served", "type": "std_srvs/Trigger"})
        for attempt in range(100):  # the service appears on the graph asynchronously
            caller.send({"op": "call_service", "service": "/hostile/served", "id": f"try {attempt}", "timeout": 1})
            try:
                request = server.receive_op("call_service", timeout=0.3)
                break
            except TimeoutError:
                assert caller.receive_op("service_response")["result"] is False
        server.send({"op": "service_response", "service": "/hostile/served", "id": request["id"], "result": False})
        assert caller.receive_op("service_response")["values"] == "Timeout exceeded while waiting for service response"
        caller.send({"op": "call_service", "service": "/hostile/served", "id": "abandoned", "timeout": 1})
        server.receive_op("call_service")
    finally:
        server.close()  # leaves the second request pending: withdrawn with the service
        caller.close()
