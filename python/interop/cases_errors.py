"""The ``errors``, ``limits`` and ``auth`` profiles: refusals are answered and the connection kept."""

from __future__ import annotations

import asyncio
import json
from typing import Any

from .outcome import Outcome
from .runner import Case, CaseContext, Deviation, Verdict
from .session import Conversation, NotAnswered, auth_message, op_is
from .steps import STRING, call_served, judge_refusal, new_id, publish_until, topic_pair
from .wire import WireClosed

__all__ = ["CASES"]


async def _leveled(context: CaseContext) -> Conversation:
    conversation = await context.connect()
    await conversation.send({"op": "set_level", "id": new_id("level"), "level": "error"})
    return conversation


async def malformed_json(context: CaseContext) -> Verdict:
    conversation = await _leveled(context)
    await conversation.send_text('{"op": "publish", "topic": ')
    return await judge_refusal(conversation, None)


async def unknown_op(context: CaseContext) -> Verdict:
    conversation = await _leveled(context)
    request_id = new_id("unknown")
    await conversation.send({"op": "interop_no_such_op", "id": request_id})
    return await judge_refusal(conversation, request_id)


async def missing_field(context: CaseContext) -> Verdict:
    conversation = await _leveled(context)
    request_id = new_id("missing")
    await conversation.send({"op": "subscribe", "id": request_id, "type": STRING})
    return await judge_refusal(conversation, request_id)


async def wrong_field_type(context: CaseContext) -> Verdict:
    conversation = await _leveled(context)
    request_id = new_id("wrongtype")
    await conversation.send({"op": "advertise", "id": request_id, "topic": 42, "type": STRING})
    return await judge_refusal(conversation, request_id)


async def unknown_type(context: CaseContext) -> Verdict:
    conversation = await _leveled(context)
    request_id = new_id("unknowntype")
    await conversation.send(
        {"op": "advertise", "id": request_id, "topic": context.name("t"), "type": "interop_nowhere_msgs/msg/Nothing"}
    )
    return await judge_refusal(conversation, request_id)


async def unknown_topic(context: CaseContext) -> Verdict:
    conversation = await _leveled(context)
    request_id = new_id("unknowntopic")
    topic = context.name("nobody_publishes")
    await conversation.send({"op": "subscribe", "id": request_id, "topic": topic})
    verdict = await judge_refusal(conversation, request_id)
    if verdict.outcome is not Outcome.FAILED or "connection is kept" not in verdict.observed:
        return verdict
    # No status: the statement lets the subscription wait for the topic. Does it?
    publisher = await context.connect("publisher")
    await publisher.send({"op": "advertise", "id": new_id("adv"), "topic": topic, "type": STRING})
    try:
        await publish_until(publisher, conversation, topic, {"data": "late"}, 8)
    except NotAnswered:
        return Verdict(Outcome.FAILED, "neither refused with a status nor kept pending until the topic appeared")
    return Verdict(Outcome.INFORMATIONAL, "no status; the subscription waited for the topic and then delivered")


async def out_of_range(context: CaseContext) -> Verdict:
    conversation = await _leveled(context)
    topic = context.name("small")
    await topic_pair(conversation, conversation, topic, "std_msgs/msg/Int8")
    await publish_until(conversation, conversation, topic, {"data": 5}, 15)
    request_id = new_id("range")
    await conversation.send({"op": "publish", "id": request_id, "topic": topic, "msg": {"data": 300}})
    verdict = await judge_refusal(conversation, request_id)
    await publish_until(conversation, conversation, topic, {"data": 7}, 10, lambda m: m.get("msg") == {"data": 7})
    wrapped = [
        m["msg"]
        for m in conversation.received
        if m.get("topic") == topic and m.get("msg") not in ({"data": 5}, {"data": 7})
    ]
    if wrapped:
        return Verdict(Outcome.FAILED, f"int8 300 was published as {wrapped[0]}")
    return verdict


# --- limits ------------------------------------------------------------------------------------


async def oversized(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    request_id = new_id("huge")
    request = {"op": "call_service", "id": request_id, "service": context.name("none"), "timeout": 1.0}
    request["args"] = {"data": "x" * (16 * 1024 * 1024)}
    try:
        try:
            await conversation.send(request)
        except OSError:  # the server may close before it read everything: its close frame tells why
            await conversation.poll(lambda m: False, 2)
        answer = await conversation.expect(lambda m: m.get("id") == request_id, 20, "an answer to a 16 MiB request")
    except WireClosed as closed:
        if closed.code == 1009:
            return Verdict(Outcome.OK, "closed with 1009 (message too big)")
        if closed.code is None:
            return Verdict(Outcome.FAILED, "the TCP connection was dropped without a close frame")
        return Verdict(Outcome.NON_STRICT, f"closed with {closed.code} {closed.reason!r} (1009 is the code for it)")
    return Verdict(Outcome.OK, f"a 16 MiB request was answered: {str(answer)[:160]}")


FLOOD = 300


async def flood(context: CaseContext) -> Verdict:
    server, caller = await context.connect_pair("server", "caller")
    service = context.name("flooded")
    await server.send(
        {"op": "advertise_service", "id": new_id("adv"), "service": service, "type": "std_srvs/srv/SetBool"}
    )
    request = {"op": "call_service", "service": service, "args": {"data": True}, "timeout": 10.0}
    await call_served(server, caller, request, {"success": True, "message": "warm"}, 20)
    ids = [new_id(f"flood{i}") for i in range(FLOOD)]
    for call_id in ids:
        await caller.send({**request, "id": call_id})

    async def answer_all() -> None:
        while True:
            incoming = await server.expect(op_is("call_service", service=service), 30, "a flooded call")
            await server.send(
                {
                    "op": "service_response",
                    "id": incoming.get("id"),
                    "service": service,
                    "result": True,
                    "values": {"success": True, "message": "ok"},
                }
            )

    answering = asyncio.ensure_future(answer_all())
    try:
        wanted = set(ids)
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 40
        while True:
            answered = {m.get("id") for m in caller.received if m.get("id") in wanted}
            if answered == wanted or loop.time() > deadline or caller.closed is not None:
                break
            await caller.poll(lambda m: False, 0.2)
    finally:
        answering.cancel()
    served = sum(1 for m in caller.received if m.get("id") in wanted and m.get("result") is True)
    missing = len(wanted - answered)
    if missing:
        closed = f", connection closed ({caller.closed.code})" if caller.closed else ""
        return Verdict(Outcome.FAILED, f"{missing} of {FLOOD} calls never answered{closed}")
    return Verdict(Outcome.OK, f"all {FLOOD} calls answered: {served} served, {FLOOD - served} refused")


# --- auth --------------------------------------------------------------------------------------


async def _not_served(context: CaseContext, stranger: Conversation) -> Verdict:
    """Whether ``stranger`` (not authenticated) is kept away from a topic an authenticated client uses."""
    friend = await context.connect("authenticated")
    topic = context.name("guarded")
    await topic_pair(friend, friend, topic, STRING)
    try:
        await stranger.send({"op": "subscribe", "id": new_id("sub"), "topic": topic, "type": STRING})
    except (WireClosed, OSError):
        return Verdict(Outcome.OK, "the server closed the connection")
    await publish_until(friend, friend, topic, {"data": "secret"}, 15)
    await publish_until(friend, friend, topic, {"data": "secret2"}, 5, lambda m: m.get("msg") == {"data": "secret2"})
    leaked = await stranger.poll(op_is("publish", topic=topic), 1.0)
    if leaked is not None:
        return Verdict(Outcome.FAILED, "the unauthenticated connection received the topic's messages")
    if stranger.closed is not None:
        return Verdict(Outcome.OK, f"closed with {stranger.closed.code}; nothing served")
    return Verdict(Outcome.OK, "nothing served (the connection stays open)")


def _need_secret(context: CaseContext) -> str:
    if context.target.credentials is None:
        raise Deviation(Outcome.FAILED, "the auth profile needs the server's secret (--secret-file)")
    return context.target.credentials.secret


async def before_auth(context: CaseContext) -> Verdict:
    _need_secret(context)
    return await _not_served(context, await context.connect("stranger", authenticate=False))


async def with_auth(context: CaseContext) -> Verdict:
    _need_secret(context)
    conversation = await context.connect()
    topic = context.name("admitted")
    await topic_pair(conversation, conversation, topic, STRING)
    await publish_until(conversation, conversation, topic, {"data": "in"}, 15)
    return Verdict(Outcome.OK, "after an HMAC auth the connection is served")


async def wrong_mac(context: CaseContext) -> Verdict:
    secret = _need_secret(context)
    stranger = await context.connect("stranger", authenticate=False)
    await stranger.send(auth_message(secret + "-wrong"))
    return await _not_served(context, stranger)


async def replayed(context: CaseContext) -> Verdict:
    secret = _need_secret(context)
    message = auth_message(secret)
    first = await context.connect("first", authenticate=False)
    await first.send(message)
    if not await first.still_serves(10):
        return Verdict(Outcome.FAILED, "a fresh auth message was not accepted")
    second = await context.connect("replay", authenticate=False)
    await second.send_text(json.dumps(message))
    verdict = await _not_served(context, second)
    if verdict.outcome is Outcome.FAILED:
        return Verdict(Outcome.NON_STRICT, "a replayed auth message was accepted")
    return verdict


def _case(number: str, profile: str, title: str, statements: tuple[str, ...], expected: str, run: Any) -> Case:
    return Case(number, title, profile, statements, expected, 40 if profile != "limits" else 75, run)


_REFUSED = "a status of level error with the id; the connection keeps serving"
CASES = (
    _case("errors.1", "errors", "malformed JSON", ("P-ERR-1", "P-STAT-2", "P-GEN-3"), _REFUSED, malformed_json),
    _case("errors.2", "errors", "unknown op", ("P-ERR-2", "P-STAT-2", "P-GEN-3"), _REFUSED, unknown_op),
    _case("errors.3", "errors", "missing field", ("P-ERR-3", "P-STAT-2", "P-GEN-3"), _REFUSED, missing_field),
    _case(
        "errors.4", "errors", "field of the wrong type", ("P-ERR-3", "P-STAT-2", "P-GEN-3"), _REFUSED, wrong_field_type
    ),
    _case("errors.5", "errors", "unknown message type", ("P-ERR-4", "P-STAT-2", "P-GEN-3"), _REFUSED, unknown_type),
    _case(
        "errors.6",
        "errors",
        "subscribe to an unknown topic without type",
        ("P-ERR-5", "P-STAT-2", "P-GEN-3"),
        _REFUSED,
        unknown_topic,
    ),
    _case(
        "errors.7",
        "errors",
        "value out of range",
        ("P-ERR-6", "P-STAT-2", "P-GEN-3"),
        "int8 300 is refused with a status, never published wrapped",
        out_of_range,
    ),
    _case("limits.1", "limits", "a 16 MiB message", ("P-LIM-1",), "close 1009 or an answer, never a hang", oversized),
    _case(
        "limits.2",
        "limits",
        f"{FLOOD} calls at once",
        ("P-LIM-2", "P-SRV-5"),
        "every call answered (served or refused)",
        flood,
    ),
    _case("auth.1", "auth", "requests before auth", ("P-AUTH-1",), "nothing is served before auth", before_auth),
    _case("auth.2", "auth", "HMAC auth", ("P-AUTH-2",), "after auth the connection is served", with_auth),
    _case("auth.3", "auth", "wrong MAC", ("P-AUTH-3",), "nothing is served after a wrong MAC", wrong_mac),
    _case("auth.4", "auth", "replayed auth", ("P-AUTH-4",), "a replayed auth message is refused", replayed),
)
