"""Steps the cases share: bringing the ROS side through the server, and judging refusals.

ROS matches a new publisher with its subscribers, and a new service with its callers,
asynchronously; the first messages of a fresh publisher may go nowhere. So a step that needs a
message to arrive repeats it until it does (within the case's time), and a step that needs a
client-served service retries a call that failed before the serving client saw it.
"""

from __future__ import annotations

import asyncio
import os
from typing import Any

from .outcome import Outcome
from .runner import Deviation, Verdict
from .session import Conversation, Matcher, NotAnswered, op_is
from .wire import WireClosed

__all__ = [
    "STRING",
    "call_served",
    "judge_refusal",
    "new_id",
    "publish_until",
    "topic_pair",
]

STRING = "std_msgs/msg/String"
_REPEAT = 0.25  # seconds between repeats of a message that has not arrived yet


def new_id(stem: str) -> str:
    return f"{stem}-{os.urandom(3).hex()}"


async def topic_pair(
    publisher: Conversation, subscriber: Conversation, topic: str, type_name: str, **subscribe: Any
) -> str:
    """``publisher`` advertises ``topic``, ``subscriber`` subscribes to it (extra subscribe fields);
    the subscription's id (an ``unsubscribe`` with it ends this subscription only)."""
    subscription = new_id("sub")
    await publisher.send({"op": "advertise", "id": new_id("adv"), "topic": topic, "type": type_name})
    await subscriber.send({"op": "subscribe", "id": subscription, "topic": topic, "type": type_name, **subscribe})
    return subscription


async def publish_until(
    publisher: Conversation,
    subscriber: Conversation,
    topic: str,
    message: dict[str, Any],
    timeout: float,
    match: Matcher | None = None,
) -> dict[str, Any]:
    """Publish ``message`` until ``subscriber`` receives something that ``match`` accepts (by
    default a ``publish`` of ``topic``); the first such message."""
    wanted = match or op_is("publish", topic=topic)
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout + subscriber.latency + subscriber.outage
    while True:
        await publisher.send({"op": "publish", "topic": topic, "msg": message})
        remaining = deadline - loop.time()
        if remaining <= 0:
            raise NotAnswered(f"nothing arrived on {topic} within {timeout:g} s of publishing")
        found = await subscriber.poll(wanted, min(_REPEAT, remaining))
        if found is not None:
            return found
        if subscriber.closed is not None:
            raise subscriber.closed
        if publisher.closed is not None:
            raise publisher.closed


async def call_served(
    server: Conversation,
    caller: Conversation,
    request: dict[str, Any],
    values: dict[str, Any],
    timeout: float,
    *,
    result: bool = True,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """``caller`` calls a service ``server`` serves, and ``server`` answers with ``values``:
    (the request as the serving client saw it, the caller's ``service_response``). A call that
    fails before the serving client saw it (the server had not discovered the service yet) is
    made again, with a fresh id."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout + caller.latency + caller.outage
    service = request["service"]
    while True:
        call_id = new_id("call")
        await caller.send({**request, "id": call_id})
        answered = op_is("service_response", id=call_id)
        seen = op_is("call_service", service=service)
        while True:
            remaining = deadline - loop.time()
            if remaining <= 0:
                raise NotAnswered(f"neither the serving client nor the caller heard of the call to {service}")
            incoming = await server.poll(seen, min(0.1, remaining))
            if incoming is not None:
                break
            early = await caller.poll(answered, 0)
            if early is not None:
                if early.get("result") is True:
                    raise Deviation(Outcome.FAILED, f"answered without the serving client: {early}")
                await asyncio.sleep(_REPEAT)  # the server has not discovered the service yet: call again
                break
            for side in (server, caller):
                if side.closed is not None:
                    raise side.closed
        if incoming is None:
            continue
        await server.send(
            {"op": "service_response", "id": incoming.get("id"), "service": service, "values": values, "result": result}
        )
        response = await caller.expect(answered, max(0.1, deadline - loop.time()), f"service_response to {call_id}")
        return incoming, response


async def judge_refusal(conversation: Conversation, request_id: str | None, timeout: float = 5.0) -> Verdict:
    """After a request the server must refuse (P-STAT-2, P-GEN-3): a ``status`` of level error
    with the request's id and a connection that still serves is OK."""

    def is_status(message: dict[str, Any]) -> bool:
        return message.get("op") == "status" and message.get("level") == "error"

    try:
        status = await conversation.expect(
            (lambda m: is_status(m) and m.get("id") == request_id) if request_id else is_status,
            timeout,
            "status of level error",
        )
    except WireClosed as closed:
        return Verdict(Outcome.FAILED, f"the server closed the connection (code {closed.code}) instead of refusing")
    except NotAnswered:
        other = await conversation.poll(is_status, 0)
        if other is not None:
            status = other
        elif await conversation.still_serves(10):
            return Verdict(Outcome.FAILED, "no status answer after set_level error (the connection is kept)")
        else:
            return Verdict(Outcome.FAILED, "no status answer, and the connection no longer serves")
    if not await conversation.still_serves(10):
        return Verdict(Outcome.FAILED, f"refused ({status.get('msg')!r}) but the connection no longer serves")
    if request_id and status.get("id") != request_id:
        return Verdict(Outcome.NON_STRICT, f"refused without the request's id: {status.get('msg')!r}")
    return Verdict(Outcome.OK, f"refused: {status.get('msg')!r}; the connection still serves")
