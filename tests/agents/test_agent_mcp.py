"""``caretaker agent`` over stdio, driven by the MCP SDK's own client, on a real ground database.

The server is the real command in a subprocess (as a desktop assistant starts it), connecting as
the consoles' role; procedures are the shipped ones (the IVA filter change released by two
operators, the EVA inspection left a draft); the runs are the recorded IVA run's records and, for
the HALT, a live run of the executive on the lab bench hosted by a "console" that serves
forwarded actions exactly as ``caretaker serve`` does (:func:`console.actions.perform_forwarded`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import shutil
import ssl
import subprocess
import sys
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from mcp import Client, StdioServerParameters
from mcp.types import CallToolResult
from sqlalchemy import insert, select, update

from agent.agent_audit import AgentRecords
from agent.mcp_server import TOKEN_ENV
from caretaker.procedure_commands import report_main
from caretaker.processes import caretaker
from console.accounts import AccountStore
from console.actions import perform_forwarded
from ground.action_requests import ActionRequests
from ground.change_feed import open_change_feed
from pride.events import EventKind
from pride.executive import Executive, Hold, Mode
from pride.run_setup import load_sysreps
from procedure_language.lint import check_procedure
from records.agent_tables import agent_proposals, agent_tokens
from records.agent_tokens import TokenStore, token_hash
from records.audit_log import AuditLog
from records.console_tables import run_hosts
from records.releases import ReleaseStore, procedure_digest
from records.robot_control import RobotControl
from support.audit import RecordedJournal
from support.certificates import self_signed_certificate
from support.executive_runs import held
from support.lab_gateway import LabGateway
from support.procedures import FIXTURES, REPO
from support.processes import COMMAND_HANG_S
from support.recorded_run import recorded_events
from support.web_server import GroundDatabase, new_ground_database

CARETAKER = Path(sys.executable).with_name("caretaker")
IVA = "iva_cdra_filter_replacement.xml"
EVA = "eva_inspection.xml"
#: Everything an agent can call: nothing that starts, approves, answers, confirms, takes or corrects.
TOOLS = {
    "list_procedures",
    "list_robots",
    "read_telemetry",
    "list_runs",
    "explain_run",
    "propose_run",
    "withdraw_proposal",
    "list_proposals",
    "request_halt",
}

pytestmark = [pytest.mark.slow(seconds=50), pytest.mark.timeout(900)]


@dataclass
class Ground:
    """A ground database with two agents, a released IVA procedure and the recorded IVA run."""

    database: GroundDatabase
    procedures: Path
    sha256: str
    tokens: dict[str, str]
    run_id: str

    def server(self, token: str, *extra: str) -> StdioServerParameters:
        args = ["agent", "--db", self.database.url, "--procedures", str(self.procedures), *extra]
        return StdioServerParameters(command=str(CARETAKER), args=args, env={**os.environ, TOKEN_ENV: token})


@pytest.fixture
def ground(request: pytest.FixtureRequest, tmp_path: Path) -> Ground:
    kind = getattr(request, "param", "sqlite")
    database = new_ground_database(
        kind, tmp_path, request.getfixturevalue("postgres") if kind == "postgresql" else None
    )
    procedures = tmp_path / "procedures"
    shutil.copytree(REPO / "procedures", procedures)
    accounts = AccountStore(database.owner_url)
    tokens = TokenStore(accounts.engine)
    log = AuditLog(database.url)
    try:
        issued = {}
        for agent in ("daphne", "hal"):
            accounts.add(agent, "agent", None)
            issued[agent] = tokens.issue(agent, timedelta(days=7)).token
        checked = check_procedure(procedures / IVA, load_sysreps([REPO / "sysrep"]))
        sha = procedure_digest(checked)
        ReleaseStore(log.engine).release_by_two(
            checked.procedure.id, sha, "alice", "bob", f"procedures/{IVA}", (procedures / IVA).read_text()
        )
        events = recorded_events()
        for event in events:
            log.append(event)
    finally:
        log.close()
        accounts.close()
    return Ground(database, procedures, sha, issued, events[0].run_id)


def with_agent(params: StdioServerParameters, scenario: Callable[[Client], Awaitable[None]]) -> None:
    async def run() -> None:
        async with Client(params) as client:
            await scenario(client)

    asyncio.run(run())


def refused(result: CallToolResult) -> str:
    """The rule a refused call names, and its message."""
    assert result.is_error, result.structured_content
    text = result.content[0].text  # type: ignore[union-attr]
    assert "refused by rule " in text, text
    return str(text.split("refused by rule ", 1)[1])


def agent_records(ground: Ground, agent: str) -> list[tuple[str, str, dict[str, Any]]]:
    """``agent``'s records (kind, tool, data), its chain checked first."""
    log = AuditLog(ground.database.url)
    try:
        records = AgentRecords(log.engine)
        check = records.verify(agent)
        assert check.ok, check.describe()
        return [(r.kind, r.instruction or "", json.loads(r.data)) for r in records.records(agent)]
    finally:
        log.close()


@pytest.mark.parametrize("ground", ["sqlite", "postgresql"], indirect=True)
def test_an_agent_reads_proposes_and_withdraws_and_every_call_is_on_its_chain(
    ground: Ground, capsys: pytest.CaptureFixture[str]
) -> None:
    control = RobotControl(ground.database.url)
    answers: dict[str, Any] = {}

    async def scenario(client: Client) -> None:
        assert {tool.name for tool in (await client.list_tools()).tools} == TOOLS
        listed = (await client.call_tool("list_procedures", {})).structured_content
        assert listed is not None
        assert [(p["file"], p["release"], p["sha256"], p["released_by"]) for p in listed["procedures"]] == [
            (IVA, 1, ground.sha256, "bob")
        ]  # the EVA inspection is a draft: not offered
        iva = listed["procedures"][0]
        assert "cdra" in iva["systems"]
        assert {
            "name": "clean_filter_id",
            "type": "string",
            "pattern": "CDRA-F-[0-9]{4}",
            "one_of": "cdra.clean_filter_ids",
        } in iva["records"]
        robots = (await client.call_tool("list_robots", {})).structured_content
        assert robots is not None and {r["robot"] for r in robots["robots"]} == {"iva", "eva"}
        runs = (await client.call_tool("list_runs", {})).structured_content
        assert runs is not None and [r["run_id"] for r in runs["runs"]] == [ground.run_id]
        told = (await client.call_tool("explain_run", {"run_id": ground.run_id})).structured_content
        assert told is not None
        assert (told["procedure"], told["outcome"]) == ("iva_cdra_filter_replacement", "completed")
        assert told["words"].startswith(f"run {ground.run_id} of iva_cdra_filter_replacement by ")
        assert told["recent"][-1]["words"] == "run completed" and told["steps"][0]["completed"] > 0

        good = {
            "procedure": IVA,
            "sha256": ground.sha256,
            "robot": "iva",
            "reason": "cabin CO2 above its yellow limit: the seated filter is saturated",
            "inputs": {"clean_filter_id": "CDRA-F-0042"},
        }
        proposed = (await client.call_tool("propose_run", good)).structured_content
        assert proposed is not None and (proposed["state"], proposed["release"]) == ("open", 1)
        answers["proposal"] = proposed["proposal_id"]
        refusals = {
            "draft": await client.call_tool("propose_run", good | {"procedure": EVA}),
            "forged": await client.call_tool("propose_run", good | {"sha256": "0" * 64}),
            "robot": await client.call_tool("propose_run", good | {"robot": "hal9000"}),
            "pattern": await client.call_tool("propose_run", good | {"inputs": {"clean_filter_id": "F-42"}}),
            "unknown input": await client.call_tool("propose_run", good | {"inputs": {"valve": "open"}}),
            "no reason": await client.call_tool("propose_run", good | {"reason": "  "}),
        }
        control.acquire("iva", "run-of-bob", "bob")  # another operator's run holds the robot
        refusals["held"] = await client.call_tool("propose_run", good)
        answers["refusals"] = {name: refused(result) for name, result in refusals.items()}
        withdrawn = (
            await client.call_tool("withdraw_proposal", {"proposal_id": proposed["proposal_id"]})
        ).structured_content
        assert withdrawn is not None and withdrawn["state"] == "withdrawn"
        answers["again"] = refused(
            await client.call_tool("withdraw_proposal", {"proposal_id": proposed["proposal_id"]})
        )
        mine = (await client.call_tool("list_proposals", {})).structured_content
        assert mine is not None and [(p["proposal_id"], p["state"]) for p in mine["proposals"]] == [
            (proposed["proposal_id"], "withdrawn")
        ]

    try:
        with_agent(ground.server(ground.tokens["daphne"]), scenario)
        # hal may not withdraw daphne's proposal (and it was withdrawn already)
        hal: dict[str, str] = {}

        async def hal_tries(client: Client) -> None:
            hal["withdraw"] = refused(await client.call_tool("withdraw_proposal", {"proposal_id": answers["proposal"]}))

        with_agent(ground.server(ground.tokens["hal"]), hal_tries)
    finally:
        control.close()
    rules = {name: text.split(":", 1)[0] for name, text in answers["refusals"].items()}
    assert rules == {
        "draft": "released_version",
        "forged": "released_version",
        "robot": "known_robot",
        "pattern": "input_pattern",
        "unknown input": "known_input",
        "no reason": "reason_given",
        "held": "one_run_per_robot",
    }
    assert "a draft (never released)" in answers["refusals"]["draft"]
    assert "no version ever released" in answers["refusals"]["forged"]
    assert "does not match the pattern CDRA-F-[0-9]{4}" in answers["refusals"]["pattern"]
    assert "run run-of-bob (user bob" in answers["refusals"]["held"]
    assert answers["again"] == f"open_proposal: proposal {answers['proposal']} is withdrawn"
    assert hal["withdraw"] == f"own_proposal: hal has no proposal {answers['proposal']} (an agent withdraws its own)"

    log = AuditLog(ground.database.url)
    try:
        with log.engine.connect() as connection:
            stored = connection.execute(select(agent_proposals)).one()
    finally:
        log.close()
    assert (stored.agent, stored.state, stored.closed_by, stored.robot, stored.binding) == (
        "daphne",
        "withdrawn",
        "daphne",
        "iva",
        "iva.yaml",
    )
    assert stored.expires - stored.created == timedelta(minutes=15)
    records = agent_records(ground, "daphne")
    assert [(kind, tool) for kind, tool, _ in records[:7]] == [
        ("answered", "connect"),
        ("answered", "list_procedures"),
        ("answered", "list_robots"),
        ("answered", "list_runs"),
        ("answered", "explain_run"),
        ("answered", "propose_run"),
        ("refused", "propose_run"),
    ]
    refusals = [data for kind, _, data in records if kind == "refused"]
    assert [r["rule"] for r in refusals] == [*rules.values(), "open_proposal"]
    assert refusals[0]["arguments"]["procedure"] == EVA and "draft" in refusals[0]["refusal"]
    assert records[5][2]["answer"]["inputs"] == {"clean_filter_id": "CDRA-F-0042"}
    assert [(kind, tool, data.get("rule")) for kind, tool, data in agent_records(ground, "hal")] == [
        ("answered", "connect", None),
        ("refused", "withdraw_proposal", "own_proposal"),
    ]
    assert_reported(ground, capsys, "daphne", [tool for _, tool, _ in records])


def assert_reported(ground: Ground, capsys: pytest.CaptureFixture[str], agent: str, tools: list[str]) -> None:
    """``caretaker report --agent`` lists each call once, in order, with its rule when refused, and the chain."""
    capsys.readouterr()
    assert report_main(["--db", ground.database.url, "--agent", agent]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[3] for line in lines[:-1]] == tools
    assert lines[-1].startswith(f"agent {agent}: chain of {len(tools)} records intact")
    draft = next(line for line in lines if "refused by rule released_version" in line)
    assert f'"procedure": "{EVA}"' in draft, draft
    log = AuditLog(ground.database.url)
    try:
        fifth = AgentRecords(log.engine).records(agent)[4]
    finally:
        log.close()
    assert report_main(["--db", ground.database.url, "--agent", agent, "--since", fifth.time.isoformat()]) == 0
    since = capsys.readouterr().out.splitlines()
    assert [int(line.split()[0]) for line in since[:-1]] == list(range(5, len(tools) + 1))
    assert report_main(["--db", ground.database.url, "--agent", "nobody"]) == 2
    assert "agent 'nobody' made no calls" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        report_main(["--db", ground.database.url, "--agent", agent, "--since", "last tuesday"])
    assert "neither a time (2026-12-06T20:00) nor a duration" in capsys.readouterr().err


def test_a_token_refused_at_start_or_revoked_mid_session_is_recorded_and_stops_the_agent(ground: Ground) -> None:
    accounts = AccountStore(ground.database.owner_url)
    tokens = TokenStore(accounts.engine)
    outcome: dict[str, str] = {}
    try:
        expired = tokens.issue("daphne", timedelta(hours=1)).token
        with accounts.engine.begin() as connection:  # an hour on
            connection.execute(
                update(agent_tokens)
                .where(agent_tokens.c.token_sha256 == token_hash(expired))
                .values(expires=datetime.now(UTC) - timedelta(seconds=1))
            )
        for token, expected in (
            (ground.tokens["hal"], "agent_token: this token belongs to another account, not to daphne"),
            ("ctk_" + "x" * 43, "agent_token: unknown token"),
            (expired, "agent_token: the token of daphne expired at "),
        ):
            params = ground.server(token, "--agent", "daphne")
            started = subprocess.run(
                [params.command, *params.args], env=params.env, capture_output=True, text=True, timeout=120, check=False
            )
            assert started.returncode == 2, started.stderr
            assert f"caretaker agent: refused by rule {expected}" in started.stderr, started.stderr

        async def revoked_meanwhile(client: Client) -> None:
            assert not (await client.call_tool("list_robots", {})).is_error
            tokens.revoke("daphne")
            outcome["after"] = refused(await client.call_tool("list_robots", {}))

        with_agent(ground.server(ground.tokens["daphne"]), revoked_meanwhile)
    finally:
        accounts.close()
    assert outcome["after"].startswith("agent_token: the token of daphne was revoked at ")
    assert [(kind, tool, data.get("rule")) for kind, tool, data in agent_records(ground, "daphne")] == [
        ("refused", "connect", "agent_token"),
        ("refused", "connect", "agent_token"),
        ("refused", "connect", "agent_token"),
        ("answered", "connect", None),
        ("answered", "list_robots", None),
        ("refused", "list_robots", "agent_token"),
    ]


def test_a_halt_an_agent_asks_for_reaches_the_console_hosting_the_run_and_is_recorded_as_the_agents(
    ground: Ground, tmp_path: Path
) -> None:
    log = AuditLog(ground.database.url)
    control = RobotControl(ground.database.url)
    accounts = AccountStore(ground.database.url)
    gateway = LabGateway(str(tmp_path / "images"))
    gateway.robot_name = "iva"
    checked = check_procedure(FIXTURES / "lab_all_kinds.xml", load_sysreps([REPO / "sysrep", FIXTURES / "sysrep"]))
    executive = Executive(checked, gateway, RecordedJournal(log), run_id="run-lab", mode=Mode.MANUAL, control=control)
    # a console hosts the run and serves the actions forwarded to it, as caretaker serve does
    console = ActionRequests(
        log.engine,
        host_id="console-a",
        console="console a",
        perform=lambda request: perform_forwarded(executive, accounts, request, "console a"),
    )
    feed = open_change_feed(log.engine)
    feed.subscribe(console.notice)
    outcome: dict[str, Any] = {}
    try:
        executive.start("alice")
        held(executive, Hold.MANUAL_MODE, "1.1")
        now = datetime.now(UTC)
        with log.engine.begin() as connection:
            connection.execute(
                insert(run_hosts).values(
                    run_id="run-lab",
                    host_id="console-a",
                    host="console a",
                    binding="iva.yaml",
                    started_by="alice",
                    claimed=now,
                    lease_until=now + timedelta(hours=1),
                    status="active",
                    mode="manual",
                    procedure_view="{}",
                    view="{}",
                    view_seq=0,
                )
            )

        async def halts(client: Client) -> None:
            outcome["nothing"] = refused(await client.call_tool("request_halt", {"robot": "eva", "reason": "why not"}))
            outcome["halt"] = (
                await client.call_tool("request_halt", {"robot": "iva", "reason": "cabin CO2 rising fast"})
            ).structured_content

        with_agent(ground.server(ground.tokens["daphne"]), halts)
        halts_recorded = [e for e in log.events("run-lab") if e.kind is EventKind.HALT]
    finally:
        feed.close()
        console.close()
        executive.stop("alice", "end of test")
        executive.join(20)
        accounts.close()
        control.close()
        log.close()
    assert outcome["nothing"] == "run_state: no run controls eva: there is nothing to halt"
    assert outcome["halt"] == {
        "words": "run run-lab on iva halted",
        "robot": "iva",
        "run_id": "run-lab",
        "outcome": "halted",
    }
    assert [(e.actor, e.data.reason) for e in halts_recorded] == [  # type: ignore[union-attr]
        ("daphne", "halt asked by agent daphne: cabin CO2 rising fast")
    ]
    assert [(kind, tool, data.get("rule")) for kind, tool, data in agent_records(ground, "daphne")][1:] == [
        ("refused", "request_halt", "run_state"),
        ("answered", "request_halt", None),
    ]


def revoke(agent: str, database: str) -> None:
    log = AuditLog(database)
    try:
        TokenStore(log.engine).revoke(agent)
    finally:
        log.close()


@contextlib.asynccontextmanager
async def over_http(url: str, token: str, ca: Path) -> AsyncIterator[Client]:
    """The SDK's own client over streamable HTTP, sending ``token`` as its bearer token."""
    import httpx2
    from mcp.client.streamable_http import streamable_http_client

    trust = ssl.create_default_context(cafile=str(ca))
    http = httpx2.AsyncClient(headers={"Authorization": f"Bearer {token}"}, verify=trust)
    async with http, Client(streamable_http_client(f"{url}/mcp", http_client=http)) as client:
        yield client


def test_over_https_each_request_needs_the_agents_own_valid_token_and_a_refused_one_is_recorded(
    ground: Ground, tmp_path: Path
) -> None:
    cert, key = self_signed_certificate(tmp_path, "ca.pem")
    common = ("agent", "--db", ground.database.url, "--procedures", str(ground.procedures), "--agent", "daphne")
    refused_options = {
        ("--listen", "0.0.0.0:0"): "must not cross a network in clear text",
        ("--listen", "here"): "expected HOST:PORT",
        ("--listen", "127.0.0.1:0", "--agent", "nobody"): "no account of role agent",
        ("--certfile", str(cert), "--keyfile", str(key)): "go with --listen",
        ("--rosbridge", "iva.yaml=http://127.0.0.1:9090"): "expected [BINDING=]ws://HOST:PORT or wss://HOST:PORT",
    }
    for options, why in refused_options.items():
        done = subprocess.run(
            [str(CARETAKER), *common, *options], capture_output=True, text=True, timeout=COMMAND_HANG_S
        )
        assert done.returncode == 2 and why in done.stderr, (options, done.stderr)
    server = caretaker(
        *common, "--listen", "127.0.0.1:0", "--certfile", str(cert), "--keyfile", str(key), env=dict(os.environ)
    )
    try:
        url = server.wait_ready(COMMAND_HANG_S).split()[2]
        assert url.startswith("https://127.0.0.1:")
        seen: dict[str, Any] = {}

        async def scenario() -> None:
            try:
                async with over_http(url, ground.tokens["daphne"], tmp_path / "ca.pem") as client:
                    listed = (await client.call_tool("list_procedures", {})).structured_content
                    assert listed is not None
                    seen["procedures"] = [p["file"] for p in listed["procedures"]]
                    explained = (await client.call_tool("explain_run", {"run_id": ground.run_id})).structured_content
                    assert explained is not None
                    seen["outcome"] = explained["outcome"]
                    revoke("daphne", ground.database.url)  # mid-session
                    await client.call_tool("list_runs", {})
                    seen["after revoking"] = "answered"
            except Exception as exc:
                seen.setdefault("after revoking", repr(exc))
            for token in (ground.tokens["hal"], "not-a-token"):
                with pytest.raises(Exception) as failed:
                    async with over_http(url, token, tmp_path / "ca.pem") as client:
                        await client.call_tool("list_runs", {})
                seen.setdefault("refused", []).append(repr(failed.value))
            import httpx2

            trust = ssl.create_default_context(cafile=str(tmp_path / "ca.pem"))
            listing = {"jsonrpc": "2.0", "id": 1, "method": "tools/list"}
            async with httpx2.AsyncClient(verify=trust) as http:  # what any HTTP client is told
                answer = await http.post(f"{url}/mcp", json=listing)
                seen["raw"] = (answer.status_code, answer.headers.get("www-authenticate", "").split(" ")[0])
                forged = {"Authorization": "Bearer forged"}  # 40 at once: each refused and recorded
                posts = (http.post(f"{url}/mcp", json=listing, headers=forged) for _ in range(40))
                burst = await asyncio.gather(*posts)
                seen["burst"] = sorted({a.status_code for a in burst})

        asyncio.run(scenario())
    finally:
        server.stop()
    assert seen.get("procedures") == [IVA] and seen.get("outcome") == "completed", seen
    # the SDK's client says only that the server answered with an error; the status and the rule are the server's
    assert "MCPError" in seen["after revoking"], seen["after revoking"]
    assert all("MCPError" in text for text in seen["refused"]), seen["refused"]
    assert seen["raw"] == (401, "Bearer"), seen["raw"]
    records = agent_records(ground, "daphne")
    assert [(kind, tool) for kind, tool, _ in records[:2]] == [
        ("answered", "list_procedures"),
        ("answered", "explain_run"),
    ]
    refusals = [(tool, data["rule"]) for kind, tool, data in records[2:] if kind == "refused"]
    assert seen["burst"] == [401], seen["burst"]
    assert len(refusals) >= 3 + 40 and {tool for tool, _ in refusals} == {"connect"}, refusals
    assert all(data.get("transport") == "http" for kind, _, data in records[2:] if kind == "refused")


def test_a_burst_of_1000_calls_gets_its_budget_answered_and_every_other_call_refused_and_recorded(
    ground: Ground,
) -> None:
    burst = 5
    outcomes: list[str] = []

    async def flood(client: Client) -> None:
        results = await asyncio.gather(*(client.call_tool("list_runs", {}) for _ in range(1000)))
        outcomes.extend(refused(r).split(":", 1)[0] if r.is_error else "answered" for r in results)

    # a rate this low refills nothing while the burst lasts, so the count is exact
    with_agent(ground.server(ground.tokens["daphne"], "--burst", str(burst), "--calls-per-second", "0.0001"), flood)
    assert outcomes.count("answered") == burst and outcomes.count("call_rate") == 1000 - burst, set(outcomes)
    records = agent_records(ground, "daphne")  # its chain checked
    assert len(records) == 1 + 1000  # connect, then every call
    assert sum(kind == "refused" and data["rule"] == "call_rate" for kind, _, data in records) == 1000 - burst


FORBIDDEN_ACTS = (
    "start_run",
    "approve_command",
    "release_procedure",
    "answer_record",
    "confirm_instruction",
    "take_robot",
    "set_mode",
    "correct_record",
    "run_draft",
)


def test_every_act_an_agent_may_not_do_is_refused_by_its_role_and_recorded(ground: Ground) -> None:
    told: dict[str, str] = {}

    async def hostile(client: Client) -> None:
        tools = {tool.name for tool in (await client.list_tools()).tools}
        assert tools == TOOLS
        for act in FORBIDDEN_ACTS:
            told[act] = refused(await client.call_tool(act, {"robot": "iva", "procedure": IVA}))

    with_agent(ground.server(ground.tokens["daphne"]), hostile)
    assert {act: text.split(":", 1)[0] for act, text in told.items()} == dict.fromkeys(FORBIDDEN_ACTS, "agent_role")
    assert "'start_run' is not an act an agent may do" in told["start_run"]
    records = agent_records(ground, "daphne")
    assert [(kind, tool, data["rule"]) for kind, tool, data in records[1:]] == [
        ("refused", act, "agent_role") for act in FORBIDDEN_ACTS
    ]
    assert records[1][2]["arguments"] == {"robot": "iva", "procedure": IVA}
    # and nothing moved: no run but the recorded one, no robot controlled, nothing proposed
    log = AuditLog(ground.database.url)
    control = RobotControl(ground.database.url)
    try:
        assert [run_id for run_id, _, _ in log.runs()] == [ground.run_id]
        assert control.holder("iva") is None and control.holder("eva") is None
        with log.engine.connect() as connection:
            assert connection.execute(select(agent_proposals.c.id)).all() == []
    finally:
        control.close()
        log.close()


def test_released_procedures_and_sysreps_are_resources_and_a_draft_is_not(ground: Ground) -> None:
    read: dict[str, Any] = {}

    async def reader(client: Client) -> None:
        for uri in (f"procedure://{IVA}", "sysrep://cdra", f"procedure://{EVA}", "sysrep://warp_drive"):
            try:
                contents = (await client.read_resource(uri)).contents
                read[uri] = contents[0].text  # type: ignore[union-attr]
            except Exception as exc:  # the SDK raises the server's refusal
                read[uri] = f"refused: {exc}"

    with_agent(ground.server(ground.tokens["daphne"]), reader)
    assert read[f"procedure://{IVA}"] == (ground.procedures / IVA).read_text()
    assert read["sysrep://cdra"] == (REPO / "sysrep" / "cdra.yaml").read_text()
    assert (
        read[f"procedure://{EVA}"].startswith("refused:") and "a draft (never released)" in read[f"procedure://{EVA}"]
    )
    assert "no SysRep 'warp_drive' here" in read["sysrep://warp_drive"]
    records = agent_records(ground, "daphne")
    assert [(kind, tool) for kind, tool, _ in records[1:]] == [
        ("answered", "read_procedure"),
        ("answered", "read_sysrep"),
        ("refused", "read_procedure"),
        ("refused", "read_sysrep"),
    ]
    assert records[1][2]["answer"] == {"name": IVA, "release": 1, "sha256": ground.sha256}  # not its text
