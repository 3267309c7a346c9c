"""Topics through the real bridge with roslibpy: pub/sub, types, options, latching."""

from __future__ import annotations

import base64
from collections.abc import Callable
from pathlib import Path

import roslibpy

from support.processes import python

from .rosbridge_support import Inbox, publish_until_received

LATE_PUBLISHER = Path(__file__).with_name("late_latched_publisher.py")


def test_publish_reaches_ros_and_echo_comes_back_in_order(connect: Callable[[], roslibpy.Ros]) -> None:
    publisher_client, subscriber_client = connect(), connect()
    inbox = Inbox()
    roslibpy.Topic(subscriber_client, "/peer/echo_out", "std_msgs/msg/String").subscribe(inbox)
    talker = roslibpy.Topic(publisher_client, "/peer/echo_in", "std_msgs/String")
    talker.advertise()
    publish_until_received(talker, {"data": "warm-up"}, inbox)
    for index in range(200):
        talker.publish(roslibpy.Message({"data": f"message {index}"}))
    # echoes of later warm-ups may still arrive among the messages: count only the messages
    received = [m["data"] for m in inbox.wait_for(200, counted=lambda m: m["data"] != "warm-up")]
    assert [r for r in received if r != "warm-up"] == [f"message {i}" for i in range(200)]


def test_latched_topic_delivers_last_value_without_a_type(connect: Callable[[], roslibpy.Ros]) -> None:
    inbox = Inbox()
    roslibpy.Topic(connect(), "/peer/latched", None).subscribe(inbox)
    assert inbox.wait_for(1)[0] == {"data": "latched value"}


def test_latched_value_reaches_a_client_subscribing_after_it_arrived(connect: Callable[[], roslibpy.Ros]) -> None:
    first, late = Inbox(), Inbox()
    roslibpy.Topic(connect(), "/peer/latched", "std_msgs/String").subscribe(first)
    assert first.wait_for(1)[0] == {"data": "latched value"}
    # the bridge's ROS subscription exists and has taken the value: the late client still gets it
    roslibpy.Topic(connect(), "/peer/latched", "std_msgs/String").subscribe(late)
    assert late.wait_for(1)[0] == {"data": "latched value"}


def test_image_with_secs_nsecs_and_uint8_list_comes_back_with_base64(connect: Callable[[], roslibpy.Ros]) -> None:
    client = connect()
    inbox = Inbox()
    topic = "/bridge_test/image"
    talker = roslibpy.Topic(client, topic, "sensor_msgs/msg/Image")
    talker.advertise()
    roslibpy.Topic(client, topic, "sensor_msgs/Image").subscribe(inbox)
    publish_until_received(
        talker,
        {"header": {"stamp": {"secs": 7, "nsecs": 9}, "frame_id": "cam"}, "width": 3, "height": 1, "data": [1, 2, 250]},
        inbox,
    )
    image = inbox.items[0]
    assert image["header"] == {"stamp": {"sec": 7, "nanosec": 9}, "frame_id": "cam"}
    assert base64.b64decode(image["data"]) == bytes([1, 2, 250])


def test_custom_affordance_template_type_round_trips(connect: Callable[[], roslibpy.Ros]) -> None:
    client = connect()
    inbox = Inbox()
    topic = "/bridge_test/waypoint"
    talker = roslibpy.Topic(client, topic, "affordance_template_msgs/msg/WaypointInfo")
    talker.advertise()
    roslibpy.Topic(client, topic, "affordance_template_msgs/WaypointInfo").subscribe(inbox)
    publish_until_received(talker, {"id": 3, "num_waypoints": 5}, inbox)
    assert inbox.items[0]["num_waypoints"] == 5


def test_throttled_subscriber_gets_one_message_while_another_gets_all(connect: Callable[[], roslibpy.Ros]) -> None:
    # separate connections: roslibpy hands every message of a topic to all its callbacks
    every, throttled = Inbox(), Inbox()
    topic = "/bridge_test/rate"
    talker = roslibpy.Topic(connect(), topic, "std_msgs/Int32")
    talker.advertise()
    roslibpy.Topic(connect(), topic, "std_msgs/Int32").subscribe(every)
    roslibpy.Topic(connect(), topic, "std_msgs/Int32", throttle_rate=600_000, queue_length=1).subscribe(throttled)
    start = publish_until_received(talker, {"data": -1}, every)
    throttled.wait_for(1)
    for index in range(30):
        talker.publish(roslibpy.Message({"data": index}))
    assert [m["data"] for m in every.wait_for(start + 30)][-1] == 29
    assert len(throttled.items) == 1


def test_latched_publisher_appearing_after_the_subscription_still_delivers(
    connect: Callable[[], roslibpy.Ros], ros_env: dict[str, str]
) -> None:
    # The bridge picks a subscription's QoS from the publishers it sees; with none yet it
    # subscribes volatile and must re-subscribe transient-local once the latched one appears.
    topic = "/bridge_test/late_latched"
    early, late = Inbox(), Inbox()
    roslibpy.Topic(connect(), topic, "std_msgs/String").subscribe(early)
    publisher = python(str(LATE_PUBLISHER), topic, env=ros_env, name="late-latched")
    try:
        publisher.wait_ready(60)
        assert early.wait_for(1)[0] == {"data": "late latched value"}
        # kept as the feed's last value, as for a topic latched from the start
        roslibpy.Topic(connect(), topic, "std_msgs/String").subscribe(late)
        assert late.wait_for(1)[0] == {"data": "late latched value"}
    finally:
        publisher.stop()
