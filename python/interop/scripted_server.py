"""``caretaker interop --serve PORT --profile clients``: a scripted rosbridge v2 server that checks a client.

It plays the cases of :mod:`interop.clients.scenarios`, one WebSocket path per case
(``ws://HOST:PORT/clients.N``), and takes the driver's reports on ``/report`` (calls of
``/interop/report`` with ``{"case": ID, "observed": {...}}``; ``hello`` names the client,
``bye`` ends the run). When the driver says bye, or at the overall timeout, every case is judged
from the frames the server saw and what the driver reported, one line per case is printed, and
the report (:mod:`interop.report`: ``index.json`` client → case → outcome, expected, observed,
duration, frames; ``index.html``) gets the client's column. The
server binds 127.0.0.1 unless told otherwise. Until the CLI wires ``--serve``:
``python -m interop.scripted_server --port P [--report DIR] [--json]``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import logging
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import websockets
from websockets.asyncio.server import ServerConnection, serve

from interop.clients.scenarios import ECHO, CaseRun, Scenario, answer, call_args, scenarios
from interop.outcome import CaseResult
from interop.report import case_line, summary, to_json, write_report

__all__ = ["REPORT_PATH", "REPORT_SERVICE", "ScriptedServer", "main", "serve_clients", "serve_main"]

log = logging.getLogger(__name__)

REPORT_PATH = "/report"
REPORT_SERVICE = "/interop/report"
PROFILE = "clients"


def frame_text(frame: str | bytes) -> str:
    """A received message as text; binary ones as the suite's records write them."""
    if isinstance(frame, str):
        return frame
    return f"<binary {len(frame)} bytes: {frame[:32].hex()}…>"


def parse(text: str) -> dict[str, Any] | None:
    """A message as a JSON object, or None (hostile input is recorded, never a traceback)."""
    try:
        message = json.loads(text)
    except (ValueError, RecursionError):
        return None
    return message if isinstance(message, dict) else None


class _Peer:
    """One connection of the client under test to a case's path; what it sends is recorded."""

    def __init__(self, run: CaseRun, connection: ServerConnection, number: int) -> None:
        self.run = run
        self.connection = connection
        self.number = number

    async def send(self, message: Mapping[str, Any]) -> None:
        text = json.dumps(message)
        self.run.record("sent", text)
        with contextlib.suppress(websockets.ConnectionClosed):
            await self.connection.send(text)

    async def close(self, code: int, reason: str) -> None:
        await self.connection.close(code, reason)

    def drop(self) -> None:
        self.connection.transport.abort()


async def default_answer(peer: _Peer, message: Mapping[str, Any]) -> None:
    """What any case answers that its scenario leaves alone: every call gets an answer (P-SRV-5)."""
    if message.get("op") != "call_service":
        return
    service = message.get("service")
    if service == "/rosapi/get_ros_version":  # what some clients ask to know they are connected
        await peer.send(answer(message, {"version": 2, "distro": "jazzy"}))
    elif service == ECHO:
        await peer.send(answer(message, {"data": call_args(message).get("data")}))
    else:
        await peer.send(answer(message, f"no service {service} in case {peer.run.scenario.case}", result=False))


class ScriptedServer:
    """The cases of one client's run, their connections, and the driver's reports."""

    def __init__(self, cases: Sequence[Scenario]) -> None:
        self.runs = {f"/{scenario.case}": CaseRun(scenario) for scenario in cases}
        self.client = "client"
        self.bye = asyncio.Event()

    async def handle(self, connection: ServerConnection) -> None:
        path = connection.request.path.split("?", 1)[0] if connection.request is not None else ""
        if path == REPORT_PATH:
            await self._reports(connection)
        elif path in self.runs and not self.runs[path].ended.is_set():
            await self._case(self.runs[path], connection)
        elif path in self.runs:
            await connection.close(1001, f"case {path[1:]} is over")
        else:
            known = ", ".join(sorted(self.runs))
            await connection.close(1008, f"unknown path {path!r}: connect to {REPORT_PATH} or one of {known}")

    async def _case(self, run: CaseRun, connection: ServerConnection) -> None:
        if run.started is None:
            run.started = time.monotonic()
        peer = _Peer(run, connection, len(run.connections) + 1)
        record: dict[str, Any] = {"number": peer.number, "opened": round(run.elapsed(), 4)}
        run.connections.append(record)
        await run.scenario.on_open(run, peer)
        try:
            async for frame in connection:
                text = frame_text(frame)
                run.record("received", text)
                message = parse(text)
                if message is not None and not await run.scenario.on_message(run, peer, message):
                    await default_answer(peer, message)
        except websockets.ConnectionClosed:
            pass
        finally:
            record["closed"] = round(run.elapsed(), 4)
            record["close"] = f"{connection.close_code} {connection.close_reason}".strip()

    async def _reports(self, connection: ServerConnection) -> None:
        """The driver's second connection: its reports, and the calls its client makes by itself."""
        with contextlib.suppress(websockets.ConnectionClosed):
            async for frame in connection:
                text = frame_text(frame)
                message = parse(text)
                if message is None or message.get("op") != "call_service":
                    continue
                if message.get("service") != REPORT_SERVICE:
                    if message.get("service") == "/rosapi/get_ros_version":
                        await connection.send(json.dumps(answer(message, {"version": 2, "distro": "jazzy"})))
                    continue
                response = await self._report(text, message)
                await connection.send(json.dumps(response))

    async def _report(self, text: str, message: Mapping[str, Any]) -> dict[str, Any]:
        args = call_args(message)
        case, observed = str(args.get("case")), args.get("observed", {})
        if isinstance(observed, str):
            observed = parse(observed)
        if not isinstance(observed, dict):
            return answer(message, f"observed must be a JSON object (or its text), not {observed!r}", result=False)
        if case == "hello":
            self.client = str(observed.get("client", self.client))
            return answer(message, {"ok": True, "cases": [path[1:] for path in self.runs]})
        if case == "bye":
            self.bye.set()
            return answer(message, {"ok": True})
        run = self.runs.get(f"/{case}")
        if run is None:
            return answer(message, f"no case {case!r}: the cases are {', '.join(self.runs)}", result=False)
        run.record("received", text)
        await run.report(observed)
        values = await run.scenario.on_report(run, observed)
        if observed.get("done"):
            run.end()
        response = answer(message, {"ok": True, **values})
        run.record("sent", json.dumps(response))
        return response

    async def finish(self, timeout: float) -> list[CaseResult]:
        """Wait for the driver's bye (at most ``timeout``), give started cases their time, judge all."""
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self.bye.wait(), timeout)
        results = []
        for run in self.runs.values():
            if run.started is not None and not run.ended.is_set():
                left = run.scenario.time_limit - run.elapsed()
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(run.ended.wait(), max(0.0, left))
            outcome, observed = run.scenario.judge(run)
            duration = run.finished_at if run.finished_at is not None else run.elapsed()
            results.append(
                CaseResult(
                    case=run.scenario.case,
                    title=run.scenario.title,
                    statements=run.scenario.statements,
                    outcome=outcome,
                    expected=run.scenario.expected,
                    observed=observed,
                    duration=round(duration, 3),
                    frames=tuple(run.frames),
                    extra={"profile": PROFILE, "connections": run.connections, "reported": run.observed},
                )
            )
        return results


async def serve_clients(port: int, *, host: str = "127.0.0.1", timeout: float = 300.0) -> tuple[str, list[CaseResult]]:
    """Serve one client's run of every case; the client's name and the results."""
    server = ScriptedServer(scenarios())
    async with serve(server.handle, host, port, max_size=16 * 1024 * 1024) as listening:
        bound = next(iter(listening.sockets)).getsockname()[1]
        print(f"serving the clients cases on ws://{host}:{bound}/clients.N, reports on {REPORT_PATH}", flush=True)
        results = await server.finish(timeout)
    return server.client, results


def serve_main(
    port: int,
    profiles: Sequence[str],
    report_dir: Path | None,
    json_out: bool,
    *,
    host: str = "127.0.0.1",
    timeout: float = 300.0,
) -> int:
    """``--serve``: 0 when every case passes (OK, NON-STRICT, INFORMATIONAL), 1 otherwise, 2 for bad arguments."""
    wrong = [profile for profile in profiles if profile != PROFILE]
    if wrong:
        print(f"--serve checks a client: profile {PROFILE!r} only, not {', '.join(wrong)}", file=sys.stderr)
        return 2
    try:
        client, results = asyncio.run(serve_clients(port, host=host, timeout=timeout))
    except OSError as exc:
        print(f"cannot serve on {host}:{port}: {exc}", file=sys.stderr)
        return 2
    if json_out:
        print(json.dumps(to_json(client, results), indent=1))
    else:
        for result in results:
            print(case_line(result))
        print()
        print(summary(results, [PROFILE]))
    if report_dir is not None:
        page = write_report(report_dir, client, results)
        print(f"report: {page}", file=sys.stderr if json_out else sys.stdout)
    return 0 if all(result.outcome.passes for result in results) else 1


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m interop.scripted_server", description="a scripted rosbridge v2 server that checks a client"
    )
    parser.add_argument("--port", type=int, required=True, help="port to serve on (0: any free port, printed)")
    parser.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    parser.add_argument("--report", type=Path, help="directory for index.json")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds to wait for the driver's bye")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    return serve_main(args.port, [PROFILE], args.report, args.json, host=args.host, timeout=args.timeout)


if __name__ == "__main__":
    sys.exit(main())
