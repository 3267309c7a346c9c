"""The clients cases can fail: a client with deliberate faults gets FAILED in the cases that show them.

The faulty client is written here on the plain WebSocket library: it matches answers to calls by
order, dies on an op it does not know, keeps a late answer for a call it had given up on and then
stops, takes a refused login for a success, and never runs the dropped-connection case. Every one of
those is FAILED; the case it gets right (the status message, which it ignores) stays OK.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import ClientConnection, connect

from interop.scripted_server import serve_main

REPO = Path(__file__).resolve().parents[2]


class Reporter:
    def __init__(self, socket: ClientConnection) -> None:
        self.socket = socket
        self.ids = itertools.count()

    async def __call__(self, case: str, observed: dict[str, Any] | str) -> dict[str, Any]:
        call_id = f"report-{next(self.ids)}"
        args = {"case": case, "observed": observed if isinstance(observed, str) else json.dumps(observed)}
        await self.socket.send(
            json.dumps({"op": "call_service", "id": call_id, "service": "/interop/report", "args": args})
        )
        while (answer := json.loads(await self.socket.recv())).get("id") != call_id:
            pass
        return dict(answer)


async def until_closed(socket: ClientConnection) -> list[dict[str, Any]]:
    """Everything the server sends until it closes; the faulty client gives up on the first unknown op."""
    seen: list[dict[str, Any]] = []
    async for frame in socket:
        message = json.loads(frame)
        if message["op"] not in ("publish", "service_response"):
            await socket.close()  # a client that dies on an op it does not know
            break
        seen.append(message)
    return seen


async def faulty_client(url: str) -> None:
    async with connect(f"{url}/report") as report_socket:
        report = Reporter(report_socket)
        refused = await report("clients.1", "[1, 2")  # a report that is no JSON object
        assert refused["result"] is False and "observed must be a JSON object" in refused["values"], refused
        await report("hello", {"client": "faulty"})
        async with connect(f"{url}/clients.1") as socket:
            for data in ("first", "second"):
                call = {"op": "call_service", "id": data, "service": "/interop/echo", "args": {"data": data}}
                await socket.send(json.dumps(call))
            answers = [json.loads(await socket.recv())["values"]["data"] for _ in range(2)]  # by order, not id
        await report("clients.1", {"first": answers[0], "second": answers[1], "done": True})
        for case, topic in (("clients.2", "/interop/fragmented"), ("clients.3", "/interop/status_after")):
            async with connect(f"{url}/{case}") as socket:
                subscribe = {"op": "subscribe", "topic": topic, "type": "std_msgs/msg/String"}
                await socket.send(json.dumps(subscribe))
                if case == "clients.3":  # status is the one op it ignores; its garbage is recorded, not fatal
                    await socket.send("not json")
                    await socket.send(b"\x00\x01")
                    received = [json.loads(await socket.recv()) for _ in range(2)][1:]
                else:
                    received = await asyncio.wait_for(until_closed(socket), 5)
            await report(case, {"received": [m["msg"]["data"] for m in received], "done": True})
        async with connect(f"{url}/clients.5") as socket:
            await socket.send(json.dumps({"op": "call_service", "id": "slow", "service": "/interop/slow"}))
            await report("clients.5", {"timeout_offered": True, "slow_call": "timed out"})
            await socket.recv()  # the late answer, for a call it forgot: it stops here
        await report("clients.5", {"after_late": "error: the client stopped", "done": True})
        async with connect(f"{url}/clients.6") as socket:
            await socket.send(json.dumps({"op": "auth", "mac": "0" * 64, "client": "c", "dest": "d", "rand": "r"}))
        await report(
            "clients.6", {"auth_offered": True, "refusal": None, "closed": False, "connected": True, "done": True}
        )
        await report("bye", {})


def test_a_faulty_client_fails_where_it_is_wrong(tmp_path: Path) -> None:
    server = subprocess.Popen(
        [sys.executable, "-m", "interop.scripted_server", "--port", "0", "--report", str(tmp_path), "--timeout", "30"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=REPO,
    )
    try:
        assert server.stdout is not None
        found = re.search(r"ws://127\.0\.0\.1:\d+", server.stdout.readline())
        assert found
        asyncio.run(faulty_client(found.group(0)))
        output, _ = server.communicate(timeout=30)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    cases = json.loads((tmp_path / "index.json").read_text())["faulty"]
    got = {case: (record["outcome"], record["observed"]) for case, record in cases.items()}
    assert {case: outcome for case, (outcome, _) in got.items()} == {
        "clients.1": "FAILED",
        "clients.2": "FAILED",
        "clients.3": "OK",
        "clients.4": "FAILED",
        "clients.5": "FAILED",
        "clients.6": "FAILED",
    }, output
    assert got["clients.1"][1] == "the first call got 'second', the second 'first'"
    assert got["clients.4"][1] == "the client never connected to this case"
    assert "new call got 'error: the client stopped'" in got["clients.5"][1]
    assert "the program was told nothing" in got["clients.6"][1]
    assert server.returncode == 1
    texts = [frame["text"] for frame in cases["clients.3"]["frames"]]
    assert "not json" in texts and "<binary 2 bytes: 0001…>" in texts


def test_serve_checks_clients_only(capsys: pytest.CaptureFixture[str]) -> None:
    assert serve_main(0, ["core"], None, False) == 2
    assert "profile 'clients' only, not core" in capsys.readouterr().err
