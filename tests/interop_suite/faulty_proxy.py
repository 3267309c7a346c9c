"""A test-only rosbridge server with one deliberate fault: a WebSocket proxy in front of a real bridge.

    python faulty_proxy.py --to ws://127.0.0.1:PORT --fault drop-status|drop-last-fragment|close-on-unknown-op

Prints ``READY proxy ws://127.0.0.1:PORT``. Every message is relayed unchanged both ways except
what the fault changes, so the suite run through it must fail exactly in the cases that cite the
statement the fault breaks (P-STAT-2, P-FRAG-3, P-ERR-2) and nowhere else. Close codes are relayed
too (the bridge's 1009 reaches the client as 1009).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import signal
from typing import Any

from websockets.asyncio.client import ClientConnection, connect
from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed

KNOWN_OPS = {
    "advertise", "unadvertise", "publish", "subscribe", "unsubscribe", "call_service", "service_response",
    "advertise_service", "unadvertise_service", "send_action_goal", "cancel_action_goal", "action_feedback",
    "action_result", "advertise_action", "unadvertise_action", "fragment", "set_level", "status", "auth", "png",
}  # fmt: skip


def _parsed(message: str | bytes) -> dict[str, Any]:
    if isinstance(message, bytes):
        return {}
    try:
        value = json.loads(message)
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _close_code(upstream: ClientConnection) -> tuple[int, str]:
    """The bridge's close code and reason, to pass on (1011 if it gave none that may be sent)."""
    frame = upstream.close_rcvd
    if frame is None or frame.code in (1005, 1006, 1015):  # codes that may not be sent on the wire
        return 1011, "upstream ended"
    return frame.code, frame.reason


async def _relay(fault: str, upstream_url: str, client: ServerConnection) -> None:
    async with connect(upstream_url, max_size=None, ping_interval=None, compression=None) as upstream:

        async def up(source: ServerConnection, sink: ClientConnection) -> None:
            async for message in source:
                op = _parsed(message).get("op")
                if fault == "close-on-unknown-op" and isinstance(op, str) and op not in KNOWN_OPS:
                    await source.close(1011, "unknown op")
                    return
                await sink.send(message)

        async def down(source: ClientConnection, sink: ServerConnection) -> None:
            async for message in source:
                parsed = _parsed(message)
                if fault == "drop-status" and parsed.get("op") == "status":
                    continue
                last = parsed.get("op") == "fragment" and parsed.get("num") == parsed.get("total", 0) - 1
                if fault == "drop-last-fragment" and last:
                    continue
                await sink.send(message)

        tasks = [asyncio.ensure_future(up(client, upstream)), asyncio.ensure_future(down(upstream, client))]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            # the end of either side, passed on to the other
            if upstream.close_code is not None and client.close_code is None:
                await client.close(*_close_code(upstream))
            if client.close_code is not None and upstream.close_code is None:
                await upstream.close()


async def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--to", required=True)
    parser.add_argument("--fault", required=True, choices=["drop-status", "drop-last-fragment", "close-on-unknown-op"])
    args = parser.parse_args()

    async def handler(client: ServerConnection) -> None:
        with contextlib.suppress(ConnectionClosed, OSError):
            await _relay(args.fault, args.to, client)

    stop = asyncio.get_running_loop().create_future()
    for sig in (signal.SIGINT, signal.SIGTERM):
        asyncio.get_running_loop().add_signal_handler(sig, stop.set_result, None)
    async with serve(handler, "127.0.0.1", 0, max_size=None, ping_interval=None, compression=None) as server:
        port = next(iter(server.sockets)).getsockname()[1]
        print(f"READY proxy ws://127.0.0.1:{port}", flush=True)
        await stop


if __name__ == "__main__":
    asyncio.run(main())
