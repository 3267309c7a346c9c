"""Hostile and malformed frames (hypothesis): the bridge answers, survives, and stays bounded."""

from __future__ import annotations

import json
from collections.abc import Iterator

import psutil
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from .rosbridge_support import RawClient, bridge_url
from support.processes import ManagedProcess, caretaker

OPS = ["advertise", "unadvertise", "publish", "subscribe", "unsubscribe", "call_service", "service_response",
       "advertise_service", "unadvertise_service", "send_action_goal", "cancel_action_goal", "action_feedback",
       "action_result", "advertise_action", "unadvertise_action", "fragment", "set_level", "auth", "png", "status"]
NAMES = st.sampled_from(["/fuzz/a", "/fuzz/b", "fuzz", "", "/", "/rosapi/topics", "/rosapi/nope", "/ä/ü", "//x",
                         "/fuzz/" + "n" * 300])
TYPES = st.sampled_from(["std_msgs/String", "std_msgs/msg/Int32", "std_srvs/srv/SetBool", "std_srvs/Trigger",
                         "caretaker_sim_msgs/action/FollowJointTrajectory", "sensor_msgs/Image", "os/system",
                         "../../etc/passwd", "std_msgs/msg/Nope", ""])
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=20),
                    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
                    max_leaves=12)
FIELD = st.sampled_from(["topic", "type", "msg", "id", "service", "args", "values", "result", "action",
                         "action_type", "throttle_rate", "queue_length", "fragment_size", "compression", "level",
                         "data", "num", "total", "timeout", "latch", "feedback", "status"])
MESSAGES = st.fixed_dictionaries({"op": st.sampled_from(OPS)}, optional={
    "topic": NAMES, "service": NAMES, "action": NAMES, "type": TYPES, "action_type": TYPES,
}).flatmap(lambda base: st.dictionaries(FIELD, JSON, max_size=4).map(lambda extra: {**extra, **base}))
FRAMES = st.one_of(
    MESSAGES.map(json.dumps),
    JSON.map(json.dumps),
    st.text(max_size=200),
    st.binary(max_size=200),
    st.integers(1, 20_000).map(lambda depth: "[" * depth + "]" * depth),
    st.integers(1, 5).map(lambda n: '{"op":"publish","topic":"/fuzz/a","msg":' * n + "{}" + "}" * n),
)


@pytest.fixture(scope="module")
def fuzz_bridge(ros_env: dict[str, str]) -> Iterator[tuple[ManagedProcess, tuple[str, int]]]:
    process = caretaker("bridge", "--port", "0", "--service-timeout", "0.5", "--log-level", "ERROR", env=ros_env)
    try:
        process.wait_ready(60)
        host, port = bridge_url(process).split("//")[1].rsplit(":", 1)
        yield process, (host, int(port))
    finally:
        process.stop()


@pytest.fixture(scope="module")
def fuzz_client(fuzz_bridge) -> Iterator[RawClient]:
    client = RawClient(*fuzz_bridge[1], max_size=None)
    client.send({"op": "set_level", "level": "error"})
    yield client
    client.close()


def still_serving(client: RawClient) -> bool:
    answer = client.request({"op": "call_service", "service": "/rosapi/get_ros_version", "id": "alive"},
                            "service_response")
    while answer.get("id") != "alive":  # answers to fuzzed calls may still be arriving
        answer = client.receive_op("service_response")
    return answer["result"] is True


@settings(max_examples=250, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(frames=st.lists(FRAMES, min_size=1, max_size=5))
def test_hostile_frames_are_answered_and_the_bridge_survives(fuzz_bridge, fuzz_client, frames) -> None:
    for frame in frames:
        fuzz_client.connection.send(frame)
    assert still_serving(fuzz_client)
    assert fuzz_bridge[0].running


def test_memory_stays_bounded_under_repeated_hostile_traffic(fuzz_bridge) -> None:
    process, address = fuzz_bridge
    rss = psutil.Process(process.proc.pid).memory_info().rss
    hostile = ['{"op":"subscribe","topic":"/fuzz/m","type":"std_msgs/String","id":%d}' % i for i in range(50)]
    hostile += ["{bad json", '{"op":"publish","topic":"/fuzz/m","msg":{"data":"x"}}', "[" * 5000 + "]" * 5000]
    for _ in range(20):
        client = RawClient(*address)
        for frame in hostile:
            client.connection.send(frame)
        assert still_serving(client)
        client.close()
    grown = psutil.Process(process.proc.pid).memory_info().rss - rss
    assert grown < 40 * 2**20, f"RSS grew by {grown / 2**20:.1f} MiB over 20 hostile connections"
