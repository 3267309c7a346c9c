"""The ``core`` profile: topics both ways, their options, type spellings and value encodings."""

from __future__ import annotations

import asyncio
import base64
import math
from typing import Any

from .outcome import Outcome
from .runner import Case, CaseContext, Verdict
from .session import NotAnswered, op_is
from .steps import STRING, new_id, publish_until, topic_pair
from .wire import WireClosed

__all__ = ["CASES"]


async def round_trip(context: CaseContext) -> Verdict:
    publisher, subscriber = await context.connect_pair("A", "B")
    topic = context.name("chatter")
    await topic_pair(publisher, subscriber, topic, STRING)
    got = await publish_until(publisher, subscriber, topic, {"data": "hello"}, 15)
    if got.get("msg") != {"data": "hello"}:
        return Verdict(Outcome.FAILED, f"delivered as {got}")
    return Verdict(Outcome.OK, "the message came back as {op: publish, topic, msg}")


async def short_type(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    topic = context.name("short")
    await topic_pair(conversation, conversation, topic, "std_msgs/String")
    try:
        got = await publish_until(conversation, conversation, topic, {"data": "short"}, 6)
    except (NotAnswered, WireClosed) as error:
        status = await conversation.poll(op_is("status"), 0)
        return Verdict(Outcome.NON_STRICT, f"std_msgs/String not carried ({status or error})")
    return Verdict(Outcome.OK, f"std_msgs/String carried: {got.get('msg')}")


async def unsubscribe(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    topic, marker = context.name("stops"), context.name("marker")
    subscription = await topic_pair(conversation, conversation, topic, STRING)
    await topic_pair(conversation, conversation, marker, STRING)
    await publish_until(conversation, conversation, topic, {"data": "before"}, 15)
    await publish_until(conversation, conversation, marker, {"data": "m0"}, 15)
    await conversation.send({"op": "unsubscribe", "id": subscription, "topic": topic})
    # Messages of the topic published before the unsubscribe may still be on their way: wait for a
    # marker sent after it, then count only what comes after that.
    await publish_until(conversation, conversation, marker, {"data": "m1"}, 15, op_is("publish", topic=marker))
    late_before = len([m for m in conversation.received if m.get("topic") == topic])
    for _ in range(4):
        await conversation.send({"op": "publish", "topic": topic, "msg": {"data": "after"}})
    await publish_until(
        conversation, conversation, marker, {"data": "m2"}, 15, lambda m: m.get("msg") == {"data": "m2"}
    )
    await context.window(0.5)  # for a wrongly delivered message to show up
    late = len([m for m in conversation.received if m.get("topic") == topic]) - late_before
    if late:
        return Verdict(Outcome.FAILED, f"{late} messages delivered after unsubscribe")
    return Verdict(Outcome.OK, "nothing delivered after unsubscribe; the other topic kept flowing")


async def latched(context: CaseContext) -> Verdict:
    publisher = await context.connect("A")
    topic = context.name("latched")
    await publisher.send({"op": "advertise", "id": new_id("adv"), "topic": topic, "type": STRING, "latch": True})
    await publisher.send({"op": "subscribe", "id": new_id("sub"), "topic": topic, "type": STRING})
    await publish_until(publisher, publisher, topic, {"data": "kept"}, 15)
    late = await context.connect("B")
    await late.send({"op": "subscribe", "id": new_id("sub"), "topic": topic, "type": STRING})
    got = await late.expect(op_is("publish", topic=topic), 8, "the latched message for a late subscriber")
    if got.get("msg") != {"data": "kept"}:
        return Verdict(Outcome.FAILED, f"late subscriber got {got}")
    await publisher.send({"op": "unadvertise", "id": new_id("unadv"), "topic": topic})
    if not await publisher.still_serves(10):
        return Verdict(Outcome.FAILED, "the connection stopped serving after unadvertise")
    return Verdict(Outcome.OK, "a later subscriber got the latched message; unadvertise kept the connection")


async def throttle(context: CaseContext) -> Verdict:
    publisher, subscriber = await context.connect_pair("A", "B")
    topic = context.name("throttled")
    await topic_pair(publisher, subscriber, topic, STRING, throttle_rate=1000)
    await publish_until(publisher, subscriber, topic, {"data": "warm"}, 15)
    received_before = len(subscriber.received)
    for index in range(40):
        await publisher.send({"op": "publish", "topic": topic, "msg": {"data": f"n{index}"}})
        await asyncio.sleep(0.05)  # 40 messages over 2 s: a 1000 ms throttle lets through 1 to 3
    await context.window(1.2)
    burst = [m for m in subscriber.received[received_before:] if str(m.get("msg", {}).get("data")).startswith("n")]
    # A message a period after the burst must pass (a link may bunch the burst into one period,
    # where a throttle rightly drops all but one or even all of it).
    await publish_until(publisher, subscriber, topic, {"data": "last"}, 15, lambda m: m.get("msg") == {"data": "last"})
    if len(burst) > 4:
        return Verdict(Outcome.NON_STRICT, f"{len(burst)} of 40 messages in 2 s delivered with throttle_rate 1000")
    return Verdict(Outcome.OK, f"{len(burst)} of 40 messages in 2 s delivered with throttle_rate 1000, a later one too")


async def queue_length(context: CaseContext) -> Verdict:
    publisher, subscriber = await context.connect_pair("A", "B")
    topic = context.name("queued")
    await topic_pair(publisher, subscriber, topic, STRING, throttle_rate=500, queue_length=2)
    await publish_until(publisher, subscriber, topic, {"data": "warm"}, 15)
    start = len(subscriber.received)
    for index in range(10):
        await publisher.send({"op": "publish", "topic": topic, "msg": {"data": f"q{index}"}})
    newest = await subscriber.poll(lambda m: m.get("msg") == {"data": "q9"}, 4)
    seen = [m.get("msg", {}).get("data") for m in subscriber.received[start:] if m.get("topic") == topic]
    if not seen:
        return Verdict(Outcome.NON_STRICT, "the throttle dropped the whole burst: queue_length 2 buffered nothing")
    if newest is None:
        return Verdict(Outcome.NON_STRICT, f"the newest message was dropped; delivered {seen}")
    return Verdict(Outcome.OK, f"delivered {seen} (the newest included)")


async def times(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    topic = context.name("time")
    await topic_pair(conversation, conversation, topic, "builtin_interfaces/msg/Time")
    got = await publish_until(conversation, conversation, topic, {"sec": 12, "nanosec": 345}, 15)
    if got.get("msg") != {"sec": 12, "nanosec": 345}:
        return Verdict(Outcome.FAILED, f"{{sec:12, nanosec:345}} came back as {got.get('msg')}")
    await conversation.send({"op": "publish", "topic": topic, "msg": {"secs": 7, "nsecs": 8}})
    legacy = await conversation.maybe(lambda m: m.get("msg") == {"sec": 7, "nanosec": 8}, 3)
    if legacy is None:
        return Verdict(Outcome.NON_STRICT, "{sec, nanosec} round trip; {secs: 7, nsecs: 8} not accepted as such")
    return Verdict(Outcome.OK, "{sec, nanosec} round trip; {secs, nsecs} accepted")


async def byte_arrays(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    topic = context.name("bytes")
    await topic_pair(conversation, conversation, topic, "std_msgs/msg/UInt8MultiArray")
    payload = bytes([0, 1, 2, 254, 255])
    encoded = base64.b64encode(payload).decode()
    got = await publish_until(conversation, conversation, topic, {"data": encoded}, 15)
    data: Any = got.get("msg", {}).get("data")
    if data != encoded:
        return Verdict(Outcome.FAILED, f"base64 {encoded!r} came back as {data!r}")
    await conversation.send({"op": "publish", "topic": topic, "msg": {"data": [9, 8, 7]}})
    listed = await conversation.maybe(lambda m: m.get("topic") == topic and m.get("msg", {}).get("data") != encoded, 3)
    expected = base64.b64encode(bytes([9, 8, 7])).decode()
    if listed is None:
        return Verdict(Outcome.NON_STRICT, "base64 round trip; a list of integers was not accepted")
    if listed["msg"]["data"] != expected:
        return Verdict(Outcome.FAILED, f"the list [9, 8, 7] came back as {listed['msg']['data']!r}")
    return Verdict(Outcome.OK, "uint8[] goes out as base64; base64 and lists are accepted")


async def not_a_number(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    topic = context.name("nan")
    await topic_pair(conversation, conversation, topic, "std_msgs/msg/Float64")
    await publish_until(conversation, conversation, topic, {"data": 1.5}, 15)
    start = len(conversation.received)
    sent_as = "NaN"
    await conversation.send_text(f'{{"op": "publish", "topic": "{topic}", "msg": {{"data": NaN}}}}')
    got = await conversation.maybe(lambda m: m.get("topic") == topic and m.get("msg", {}).get("data") != 1.5, 3)
    if got is None:
        sent_as = "null"
        await conversation.send({"op": "publish", "topic": topic, "msg": {"data": None}})
        got = await conversation.maybe(lambda m: m.get("topic") == topic and m.get("msg", {}).get("data") != 1.5, 3)
    if got is None:
        return Verdict(Outcome.FAILED, "a NaN was delivered neither when sent as a NaN token nor as null")
    index = conversation.received.index(got, start)
    raw = conversation.raw[index]
    value = got["msg"]["data"]
    if value is not None and not (isinstance(value, float) and math.isnan(value)):
        return Verdict(Outcome.FAILED, f"NaN (sent as {sent_as}) came back as {value!r}")
    if value is None:
        return Verdict(Outcome.OK, f"NaN (sent as {sent_as}) delivered as null")
    return Verdict(Outcome.NON_STRICT, f"NaN (sent as {sent_as}) delivered as a bare token: {raw!r}")


def _case(number: str, title: str, statements: tuple[str, ...], expected: str, run: Any, timeout: float = 30) -> Case:
    return Case(number, title, "core", statements, expected, timeout, run)


CASES = (
    _case(
        "core.1",
        "publish reaches a subscriber through the server",
        ("P-ADV-1", "P-PUB-1", "P-PUB-3", "P-SUB-1", "P-TYPE-1"),
        "the published std_msgs/msg/String arrives as {op: publish, topic, msg}",
        round_trip,
    ),
    _case(
        "core.2", "type spelled pkg/T", ("P-TYPE-2",), "std_msgs/String is accepted as std_msgs/msg/String", short_type
    ),
    _case("core.3", "unsubscribe stops delivery", ("P-SUB-5",), "no message after unsubscribe", unsubscribe),
    _case(
        "core.4",
        "latched topic reaches a late subscriber; unadvertise",
        ("P-ADV-2", "P-ADV-3"),
        "a subscriber that comes later gets the last latched message",
        latched,
    ),
    _case("core.5", "throttle_rate", ("P-SUB-3",), "at most one message per second with throttle_rate 1000", throttle),
    _case(
        "core.6",
        "queue_length keeps the newest",
        ("P-SUB-4",),
        "with throttle_rate 500 and queue_length 2, the newest of a burst of 10 arrives",
        queue_length,
    ),
    _case("core.7", "times", ("P-VAL-1", "P-VAL-2"), "{sec, nanosec} round trip, {secs, nsecs} accepted", times),
    _case(
        "core.8",
        "byte arrays",
        ("P-VAL-3", "P-VAL-4", "P-PUB-2"),
        "uint8[] out as base64; base64 and a list accepted in",
        byte_arrays,
    ),
    _case("core.9", "NaN", ("P-VAL-5", "P-VAL-6"), "a NaN float is delivered, as null", not_a_number),
)
