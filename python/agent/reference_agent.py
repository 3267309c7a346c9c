"""``caretaker agent --reference``: a deterministic assistant that answers an anomaly with the MCP tools alone.

It is an MCP client of ``caretaker agent``, which it starts as its own server over stdio with the
same options and token, so it can do exactly what any MCP client connected as that agent could,
and nothing more. It is the project's reference for how an assistant closes the paper's loop
(an alarm, a diagnosis, a proposed procedure, an operator's acceptance, the robot's run, the
alarm cleared):

1. **Watch**: ``read_telemetry`` of the robot until an item is out of its limits (the alarm).
2. **Diagnose**: ``list_procedures``; the released procedure that declares it responds to that
   item at that state (``responds_to``: a yellow response answers yellow and red). None: it says
   so and goes on watching.
3. **Propose**: ``propose_run`` of that version, citing the item, its reason in words (the item,
   its value and limit, the procedure's own words), and for each record that names the telemetry
   listing its allowed values (``one_of``), the first value listed now.
4. **Follow**: ``list_proposals`` until an operator answers. Declined or expired: it says why and
   watches again (it does not propose the same thing twice for one alarm). Accepted:
   ``explain_run`` of the run until it ends, saying each time the run starts to wait for an
   operator (a hold, a question, an approval) and what it waits for.
5. **Confirm**: ``read_telemetry`` until the item is within its limits again: the alarm cleared.

Each milestone is one line, ``TIMELINE EVENT ISO-TIME words``, so a demo or a test reads the
timeline from its output. Exit 0 when the alarm cleared, 1 when the run did not complete or
the time given ran out, 2 when the server refused the agent.
"""

from __future__ import annotations

import asyncio
import os
import sys
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from mcp import Client, StdioServerParameters
from mcp.shared.exceptions import MCPError

__all__ = ["ReferenceAgent", "server_arguments"]

#: Options of ``caretaker agent`` that are the reference agent's own, with whether each takes a value.
REFERENCE_OPTIONS = {"--reference": False, "--robot": True, "--watch-every": True, "--within": True}
#: Outcomes of a run that has ended (``explain_run``).
ENDED = ("completed", "stopped", "interrupted")


def server_arguments(argv: Sequence[str]) -> list[str]:
    """``caretaker agent``'s arguments without the reference agent's own (its server's command line)."""
    kept: list[str] = []
    skip = False
    for argument in argv:
        if skip:
            skip = False
            continue
        name = argument.split("=", 1)[0]
        if name in REFERENCE_OPTIONS:
            skip = REFERENCE_OPTIONS[name] and "=" not in argument
            continue
        kept.append(argument)
    return kept


class AgentStopped(Exception):
    """The server refused a call, or the run did not complete: the message says which."""


class ReferenceAgent:
    """Watches ``robot`` through ``client`` every ``every`` s and answers its first anomaly."""

    def __init__(self, client: Client, robot: str, every: float) -> None:
        self.client = client
        self.robot = robot
        self.every = every

    async def call(self, tool: str, **arguments: Any) -> dict[str, Any]:
        result = await self.client.call_tool(tool, arguments)
        if result.is_error or result.structured_content is None:
            text = result.content[0].text if result.content else "no answer"  # type: ignore[union-attr]
            raise AgentStopped(f"{tool}: {text}")
        return dict(result.structured_content)

    async def answer_anomaly(self) -> None:
        """Watch, diagnose, propose, follow and confirm, as the module says."""
        proposed: set[tuple[str, str]] = set()  # (item, procedure): proposed for this alarm already
        while True:
            item = await self._alarm()
            procedure = await self._responding(item)
            if procedure is None or (item["name"], procedure["file"]) in proposed:
                await asyncio.sleep(self.every)
                continue
            proposed.add((item["name"], procedure["file"]))
            proposal = await self._propose(item, procedure)
            run_id = await self._answered(proposal)
            if run_id is None:
                continue
            await self._run_ended(run_id)
            await self._cleared(item)
            return

    async def _alarm(self) -> dict[str, Any]:
        """The first item out of its limits, once one is (its entry, with ``name``: SYSTEM.ITEM)."""
        while True:
            read = await self.call("read_telemetry", robot=self.robot)
            for entry in read["items"]:
                if entry["state"] in ("yellow", "red"):
                    name = f"{entry['system']}.{entry['item']}"
                    say(
                        "alarm",
                        f"{name} = {shown(entry)} is {entry['limit']}",
                    )
                    return {**entry, "name": name}
            await asyncio.sleep(self.every)  # nothing pushes telemetry over MCP: read it again

    async def _responding(self, item: dict[str, Any]) -> dict[str, Any] | None:
        listed = await self.call("list_procedures")
        for procedure in listed["procedures"]:
            for response in procedure["responds_to"]:
                answers = response["state"] == item["state"] or response["state"] == "yellow"
                if (response["system"], response["item"]) == (item["system"], item["item"]) and answers:
                    say(
                        "diagnosis",
                        f"{procedure['file']} (release {procedure['release']}) responds: {response['text']}",
                    )
                    return dict(procedure)
        say("diagnosis", f"no released procedure responds to {item['name']} at {item['state']}; watching on")
        return None

    async def _propose(self, item: dict[str, Any], procedure: dict[str, Any]) -> int:
        read = await self.call("read_telemetry", robot=self.robot)
        now = {f"{e['system']}.{e['item']}": e for e in read["items"]}
        inputs = {}
        for record in procedure["records"]:
            listing = now.get(record["one_of"] or "")
            if listing is not None and listing["value"]:
                inputs[record["name"]] = str(listing["value"]).split(",")[0].strip()
        response = next(
            r for r in procedure["responds_to"] if (r["system"], r["item"]) == (item["system"], item["item"])
        )
        reason = f"{item['name']} is {item['limit']} ({shown(item)}): {response['text']}"
        cited = [item["name"], *(record["one_of"] for record in procedure["records"] if record["one_of"] in now)]
        proposal = await self.call(
            "propose_run",
            procedure=procedure["file"],
            sha256=procedure["sha256"],
            robot=self.robot,
            reason=reason,
            inputs=inputs,
            cited=list(dict.fromkeys(cited)),
        )
        say("proposal", f"proposal {proposal['proposal_id']}: {procedure['file']} on {self.robot}, inputs {inputs}")
        return int(proposal["proposal_id"])

    async def _answered(self, proposal_id: int) -> str | None:
        """The run an operator started by accepting the proposal; None when it was declined or expired."""
        while True:
            listed = await self.call("list_proposals")
            mine = next(p for p in listed["proposals"] if p["proposal_id"] == proposal_id)
            if mine["state"] == "accepted" and mine["run_id"]:
                say("acceptance", f"accepted by {mine['answered_by']}: run {mine['run_id']}")
                return str(mine["run_id"])
            if mine["state"] in ("declined", "expired", "withdrawn"):
                why = f": {mine['answer']}" if mine["answer"] else ""
                say("unanswered", f"proposal {proposal_id} {mine['state']}{why}")
                return None
            await asyncio.sleep(self.every)

    async def _run_ended(self, run_id: str) -> None:
        started = False
        waiting = ""  # what the run waits for, as last said
        while True:
            try:
                told = await self.call("explain_run", run_id=run_id)
            except AgentStopped as exc:
                if "rule known_run" not in str(exc):
                    raise
                await asyncio.sleep(self.every)  # its first records are on their way down from the habitat
                continue
            if not started:
                say("start", f"run {run_id} started by {told['started_by']} at {told['started']}")
                started = True
            if told["waiting_for"] and told["waiting_for"] != waiting:
                say("waiting", f"run {run_id} waits for an operator: {told['waiting_for']}")
            waiting = told["waiting_for"]
            if told["outcome"] in ENDED:
                if told["outcome"] != "completed":
                    raise AgentStopped(f"run {run_id} {told['outcome']}: {told['words']}")
                say("completion", told["words"])
                return
            await asyncio.sleep(self.every)

    async def _cleared(self, item: dict[str, Any]) -> None:
        while True:
            read = await self.call("read_telemetry", robot=self.robot)
            entry = next(e for e in read["items"] if (e["system"], e["item"]) == (item["system"], item["item"]))
            if entry["state"] == "green":
                say("cleared", f"{item['name']} = {shown(entry)} is within its limits")
                return
            await asyncio.sleep(self.every)


def shown(entry: dict[str, Any]) -> str:
    """A telemetry entry's value with its units, a number to four significant digits."""
    value = entry["value"]
    text = f"{value:.4g}" if isinstance(value, float) else str(value)
    return f"{text} {entry['units']}" if entry["units"] else text


def say(event: str, words: str) -> None:
    """One timeline line (the words are data: they may quote the habitat's text)."""
    print(f"TIMELINE {event} {datetime.now(UTC).isoformat(timespec='milliseconds')} {words}", flush=True)


def run(argv: Sequence[str], robot: str, every: float, within: float | None) -> int:
    """Start ``caretaker agent ARGV`` as this agent's server and answer ``robot``'s first anomaly."""
    caretaker = str(Path(sys.executable).with_name("caretaker"))
    params = StdioServerParameters(command=caretaker, args=["agent", *argv], env=dict(os.environ))

    stopped: list[AgentStopped] = []

    async def answer() -> None:
        async with Client(params) as client:
            try:
                await ReferenceAgent(client, robot, every).answer_anomaly()
            except AgentStopped as exc:  # here, not through the client's task group, which would wrap it
                stopped.append(exc)

    started = time.monotonic()
    try:
        asyncio.run(asyncio.wait_for(answer(), within))
    except (TimeoutError, MCPError, OSError) as exc:
        print(f"caretaker agent --reference: gave up after {time.monotonic() - started:.0f} s: {exc}", file=sys.stderr)
        return 1
    if stopped:
        print(f"caretaker agent --reference: {stopped[0]}", file=sys.stderr)
        return 2 if "refused by rule" in str(stopped[0]) else 1
    return 0
