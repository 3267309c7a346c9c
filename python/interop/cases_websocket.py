"""The ``websocket`` profile: the RFC 6455 layer under rosbridge (what Autobahn|Testsuite covers)."""

from __future__ import annotations

import asyncio
import json
from typing import Any

from .outcome import Outcome
from .runner import Case, CaseContext, Verdict
from .session import Conversation, op_is
from .steps import new_id
from .wire import CLOSE, TEXT, WireClosed, build_frame

__all__ = ["CASES"]


async def _closed_with(conversation: Conversation, code: int, timeout: float = 10) -> Verdict:
    """Judge how the server ended a connection it had to fail with ``code``."""
    try:
        await conversation.expect(lambda m: False, timeout, f"close {code}")
    except WireClosed as closed:
        if closed.code == code:
            return Verdict(Outcome.OK, f"closed with {code}")
        if closed.code is None:
            return Verdict(Outcome.NON_STRICT, f"TCP dropped without a close frame ({code} expected)")
        return Verdict(Outcome.NON_STRICT, f"closed with {closed.code} {closed.reason!r} ({code} expected)")
    return Verdict(Outcome.FAILED, f"the connection stayed open ({code} expected)")


async def fragmented_message(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    call_id = new_id("split")
    text = json.dumps({"op": "call_service", "id": call_id, "service": context.name("none"), "timeout": 1.0})
    third = len(text) // 3
    await conversation.socket.send_fragmented([text[:third], text[third : 2 * third], text[2 * third :]])
    answer = await conversation.expect(op_is("service_response", id=call_id), 15, "the answer to a message in 3 frames")
    return Verdict(Outcome.OK, f"a message in 3 frames was answered (result {answer.get('result')})")


async def ping_pong(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    payload = b"interop-ping-" + new_id("p").encode()
    await conversation.socket.ping(payload)
    try:
        pong = await asyncio.wait_for(conversation.socket.pongs.get(), 10)
    except TimeoutError:
        return Verdict(Outcome.FAILED, "no pong within 10 s")
    if pong != payload:
        return Verdict(Outcome.FAILED, f"pong payload {pong!r}, ping was {payload!r}")
    return Verdict(Outcome.OK, "pong with the ping's payload")


async def invalid_utf8(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    await conversation.socket.send_raw(build_frame(TEXT, b'{"op": "\xff\xfe"}'), "<text frame with invalid UTF-8>")
    return await _closed_with(conversation, 1007)


async def close_echoed(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    await conversation.socket.send_raw(build_frame(CLOSE, (1000).to_bytes(2, "big")), "<close 1000>")
    try:
        await conversation.expect(lambda m: False, 10, "the close answer")
    except WireClosed as closed:
        if closed.code == 1000:
            return Verdict(Outcome.OK, "the close was answered with 1000")
        return Verdict(Outcome.FAILED, f"the close was answered with {closed.code}")
    return Verdict(Outcome.FAILED, "the close was not answered")


async def unmasked(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    message = json.dumps({"op": "call_service", "id": "unmasked", "service": context.name("none")}).encode()
    await conversation.socket.send_raw(build_frame(TEXT, message, masked=False), "<unmasked text frame>")
    return await _closed_with(conversation, 1002)


async def reserved_opcode(context: CaseContext) -> Verdict:
    conversation = await context.connect()
    await conversation.socket.send_raw(build_frame(0x3, b"reserved"), "<frame with reserved opcode 3>")
    return await _closed_with(conversation, 1002)


def _case(number: str, title: str, statements: tuple[str, ...], expected: str, run: Any) -> Case:
    return Case(number, title, "websocket", statements, expected, 25, run)


CASES = (
    _case("websocket.1", "message in continuation frames", ("P-WS-1",), "handled as one message", fragmented_message),
    _case("websocket.2", "ping", ("P-WS-2",), "a pong with the same payload", ping_pong),
    _case("websocket.3", "invalid UTF-8", ("P-WS-3",), "close 1007", invalid_utf8),
    _case("websocket.4", "client close", ("P-WS-4",), "the close answered with 1000", close_echoed),
    _case("websocket.5", "unmasked client frame", ("P-WS-5",), "close 1002", unmasked),
    _case("websocket.6", "reserved opcode", ("P-WS-6",), "close 1002", reserved_opcode),
)
