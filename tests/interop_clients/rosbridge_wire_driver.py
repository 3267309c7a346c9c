"""Drives the project's Python client (``rosbridge_wire.client.RosbridgeClient``) through the
``clients`` cases of ``caretaker interop --serve``.

``python tests/interop_clients/rosbridge_wire_driver.py ws://127.0.0.1:PORT``. It lives with the
tests, not in ``python/interop/clients/`` beside the other drivers: the suite must import nothing
of the bridge's code, and this driver imports the client under test. One client per case on the
case's path, used as the console and the onboard executive use it; one more on ``/report`` tells
the server what the program received. The waits are the driver's patience with the client.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import sys
from collections.abc import Mapping
from typing import Any

from rosbridge_wire.client import Endpoint, LinkError, RosbridgeClient, Subscription

PATIENCE = 3.0


class Driver:
    def __init__(self, url: str) -> None:
        self.url = url.rstrip("/")
        self.reporter = RosbridgeClient(Endpoint(f"{self.url}/report"), name="interop-report")

    async def report(self, case: str, observed: dict[str, Any]) -> Mapping[str, Any]:
        print(f"{case}: {json.dumps(observed)[:200]}", flush=True)
        return await self.reporter.call(
            "/interop/report", {"case": case, "observed": json.dumps(observed)}, timeout=30.0
        )

    async def open(self, case: str, **endpoint: Any) -> RosbridgeClient:
        client = RosbridgeClient(Endpoint(f"{self.url}/{case}", **endpoint), name=f"interop-{case}")
        client.start()
        if not endpoint:
            await asyncio.wait_for(client.ready.wait(), 10)
        return client

    async def out_of_order(self) -> None:
        client = await self.open("clients.1")

        async def call(data: str) -> Any:
            try:
                return (await client.call("/interop/echo", {"data": data}, timeout=2 * PATIENCE)).get("data")
            except LinkError as exc:
                return f"error: {exc}"

        first, second = await asyncio.gather(call("first"), call("second"))
        await self.report("clients.1", {"first": first, "second": second, "done": True})
        await client.close()

    async def messages(self, case: str, topic: str) -> None:
        client = await self.open(case)
        received: list[Any] = []
        after = asyncio.Event()

        def receive(message: Mapping[str, Any]) -> None:
            received.append(message.get("data"))
            if message.get("data") == "after":
                after.set()

        client.subscribe(Subscription(topic, "std_msgs/msg/String", receive))
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(after.wait(), PATIENCE)
        # the client logs a status message and hands the program nothing
        await self.report(case, {"received": received, "status": None, "done": True})
        await client.close()

    async def dropped(self) -> None:
        client = await self.open("clients.4")
        received: list[Any] = []
        arrived = asyncio.Event()

        def receive(message: Mapping[str, Any]) -> None:
            received.append(message.get("data"))
            if message.get("data") == "after-reconnect":
                arrived.set()

        async def serve(args: Mapping[str, Any]) -> Mapping[str, Any]:
            return {"success": True, "message": "served"}

        client.subscribe(Subscription("/interop/drop", "std_msgs/msg/String", receive))
        client.advertise_service("/interop/drop_service", "std_srvs/srv/Trigger", serve)
        registered = ["subscribe /interop/drop", "advertise_service /interop/drop_service"]
        answer = await self.report("clients.4", {"registered": registered})
        if answer.get("reconnected"):
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(arrived.wait(), PATIENCE)
        await self.report("clients.4", {"received": received, "done": True})
        await client.close()

    async def slow(self) -> None:
        client = await self.open("clients.5")
        try:
            await client.call("/interop/slow", {}, timeout=0.5)
            outcome = "answered"
        except LinkError as exc:
            outcome = "timed out" if "no answer in time" in str(exc) else f"error: {exc}"
        await self.report("clients.5", {"timeout_offered": True, "slow_call": outcome})
        try:
            after = (await client.call("/interop/echo", {"data": "after-late"}, timeout=PATIENCE)).get("data")
        except LinkError as exc:
            after = f"error: {exc}"
        await self.report("clients.5", {"after_late": after, "done": True})
        await client.close()

    async def refused_auth(self) -> None:
        closed = asyncio.Event()
        client = RosbridgeClient(
            Endpoint(f"{self.url}/clients.6", secret="not the server's secret"),
            name="interop-clients.6",
            on_state=lambda state: closed.set() if state == "reconnecting" else None,
        )
        client.start()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(closed.wait(), PATIENCE)
        # the close reason reaches only the log; the program learns "reconnecting"
        observed = {"auth_offered": True, "refusal": None, "closed": closed.is_set(), "connected": client.connected}
        await self.report("clients.6", {**observed, "done": True})
        await client.close()

    async def run(self) -> None:
        self.reporter.start()
        await asyncio.wait_for(self.reporter.ready.wait(), 10)
        try:
            await self.report("hello", {"client": "caretaker rosbridge_wire.client"})
            await self.out_of_order()
            await self.messages("clients.2", "/interop/fragmented")
            await self.messages("clients.3", "/interop/status_after")
            await self.dropped()
            await self.slow()
            await self.refused_auth()
            await self.report("bye", {})
        finally:
            await self.reporter.close()


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not argv[0].startswith(("ws://", "wss://")):
        print("usage: rosbridge_wire_driver.py ws://HOST:PORT", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.ERROR)
    asyncio.run(Driver(argv[0]).run())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
