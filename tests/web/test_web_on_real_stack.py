"""The IVA procedure in a real browser, on the real robot stack, started from an agent's proposal.

``caretaker up --scene iva`` (simulation, planner, AT server, rosbridge: separate processes) and
``caretaker serve`` with the JVM-hosted PAX plugins behind the executive. An assistant agent
(``caretaker agent`` over stdio, driven by the MCP SDK's own client) lists the released IVA
procedure, reads the robot's telemetry against its limits (the cabin's CO2 from the simulator),
and proposes the filter change twice, citing the CO2; every console lists the proposals with the
cited values then and now, observers without answers. alice declines one with a reason the agent
reads back, and accepts the other in manual mode: the run starts under her name. Then: Send the
first command and see its result and the audit record with the
user's id; switch to autonomous: the hazardous unlock waits for a second operator (the sender is
offered no Approve…, her own approval through the API is refused and recorded), bob approves it
from his console; watch PAX stop at the manual instruction; let PAX carry the
real arm through steps 2 and 3 to the record of the clean filter's id, enter it, and see PAX send
it in the next command (an id the rack does not report as a clean filter is refused; one the
operator re-enters is used, both values logged), and the run completes, its report naming both
operators of the unlock; an observer watching the same run cannot Send, and the server refuses
it when forced, on the record. The run's record names the proposal and the agent; the agent reads
what became of both proposals. (test_operator_view.py covers the rest of the page on simulated systems.)
"""

from __future__ import annotations

import asyncio
import re
import sys
from collections.abc import Awaitable, Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from mcp import Client, StdioServerParameters
from playwright.sync_api import Page, expect

from agent.mcp_server import TOKEN_ENV
from console.accounts import AccountStore
from pride.run_setup import load_sysreps
from procedure_language.lint import check_procedure
from records.agent_tokens import TokenStore
from records.audit_log import AuditLog
from records.releases import ReleaseStore, procedure_digest
from support.operator_page import (
    IVA,
    UNLOCK,
    audit_row,
    expect_current,
    expect_ended,
    instruction,
    screenshot,
    send_for_approval,
)
from support.web_server import REPO, WebServer, server_on_real_stack

#: PAX plans and moves the arm on the way to a hold: real motion, as slow as the machine's load makes it.
MOTION_MS = 180_000

#: The whole procedure's motions under the suite's load can pass the suite's 300 s per test while
#: each wait (MOTION_MS) is still in time: those waits must be what fails, with what the page shows.
pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=60), pytest.mark.timeout(1500)]


CARETAKER = Path(sys.executable).with_name("caretaker")
REASON = "cabin CO2 is rising: the filter seated in the CDRA cabinet is near saturation"
CITED = ["cdra.co2_partial_pressure", "cdra.installed_filter_id"]


def released_iva(server: WebServer) -> str:
    """Release the IVA procedure in the server's ground database (alice and bob); its sha256."""
    checked = check_procedure(server.procedures / IVA, load_sysreps([REPO / "sysrep"]))
    sha = procedure_digest(checked)
    log = AuditLog(server.database.url)
    try:
        text = (server.procedures / IVA).read_text()
        ReleaseStore(log.engine).release_by_two(checked.procedure.id, sha, "alice", "bob", f"procedures/{IVA}", text)
    finally:
        log.close()
    return sha


def agent_session(server: WebServer, env: dict[str, str], scenario: Callable[[Client], Awaitable[None]]) -> None:
    """Run ``scenario`` with the MCP SDK's client on ``caretaker agent`` as daphne (its account made at first use),
    reaching the server's ground database and, as the server does, its robot."""
    accounts = AccountStore(server.database.owner_url)
    try:
        if accounts.get("daphne") is None:
            accounts.add("daphne", "agent", None)
        token = TokenStore(accounts.engine).issue("daphne", timedelta(hours=1)).token
    finally:
        accounts.close()
    arguments = ["agent", "--db", server.database.url, "--procedures", str(server.procedures)]
    params = StdioServerParameters(
        command=str(CARETAKER),
        args=[*arguments, "--rosbridge", f"iva.yaml={server.rosbridge}"],
        env={**env, TOKEN_ENV: token},
    )

    async def run() -> None:
        async with Client(params) as client:
            await scenario(client)

    with ThreadPoolExecutor(1) as thread:  # Playwright's sync API holds this thread's event loop
        thread.submit(asyncio.run, asyncio.wait_for(run(), 180)).result()


async def answer(client: Client, tool: str, **arguments: Any) -> dict[str, Any]:
    """A tool's structured answer (the call must not be refused)."""
    result = await client.call_tool(tool, arguments)
    assert not result.is_error and result.structured_content is not None, result.content
    return result.structured_content


def agent_proposes(server: WebServer, env: dict[str, str]) -> dict[str, Any]:
    """daphne reads the IVA robot's telemetry and proposes the filter change twice; what she saw and made."""
    seen: dict[str, Any] = {}

    async def scenario(client: Client) -> None:
        [iva] = (await answer(client, "list_procedures"))["procedures"]
        assert iva["file"] == IVA and [(r["system"], r["item"]) for r in iva["responds_to"]] == [
            ("cdra", "co2_partial_pressure")
        ]
        while True:  # the PAX host connects and subscribes at the first ask; its values follow
            read = await answer(client, "read_telemetry", robot="iva")
            items = {f"{i['system']}.{i['item']}": i for i in read["items"]}
            if all(items[name]["value"] is not None for name in CITED):
                break
            await asyncio.sleep(0.5)  # nothing to await across MCP: ask again, within the call budget
        unknown = await client.call_tool("read_telemetry", {"robot": "hal9000"})
        miscited = await client.call_tool(
            "propose_run",
            {"procedure": IVA, "sha256": iva["sha256"], "robot": "iva", "reason": REASON, "cited": ["cdra.nope"]},
        )
        proposal = {"procedure": IVA, "sha256": iva["sha256"], "robot": "iva"}
        first = await answer(client, "propose_run", **proposal, reason=REASON, cited=CITED)
        second = await answer(client, "propose_run", **proposal, reason="swap it now, to be safe")
        seen.update(items=items, read=read, first=first, second=second)
        seen["refused"] = [r.content[0].text for r in (unknown, miscited)]  # type: ignore[union-attr]

    agent_session(server, env, scenario)
    return seen


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, ros_env: dict[str, str]) -> Iterator[WebServer]:
    """The IVA stack and a web server on it (overrides conftest's simulated one for this module)."""
    with server_on_real_stack(tmp_path_factory.mktemp("web_real"), REPO / "procedures", ros_env) as served:
        yield served


def test_operator_runs_the_iva_procedure_and_an_observer_only_watches(
    sign_in: Callable[[str], Page], server: WebServer, ros_env: dict[str, str]
) -> None:
    released_iva(server)
    seen = agent_proposes(server, ros_env)
    co2 = seen["items"]["cdra.co2_partial_pressure"]
    assert 2.0 <= co2["value"] <= 3.0 and co2["units"] == "mmHg", co2  # the cabin as the ISS keeps it
    assert (co2["state"], co2["limit"]) == ("green", None) and seen["read"]["out_of_limits"] == []
    assert seen["items"]["cdra.filter_locked"]["value"] is True  # the dirty filter is locked in its cabinet
    assert "refused by rule known_robot" in seen["refused"][0]
    assert "refused by rule known_telemetry" in seen["refused"][1] and "cdra.nope" in seen["refused"][1]
    first, second = seen["first"], seen["second"]
    assert [(c["item"], c["state"]) for c in first["cited"]] == [
        ("co2_partial_pressure", "green"),
        ("installed_filter_id", "no limits"),
    ]

    # every console lists the proposals; alice declines one with a reason and accepts the other
    alice = sign_in("alice")
    expect(alice.locator("#who")).to_have_text("alice (operator)")
    card = alice.locator(f'#proposal-list li[data-proposal-id="{first["proposal_id"]}"]')
    expect(card).to_have_attribute("data-state", "open")
    expect(card).to_contain_text(f"daphne proposes {IVA} (release 1) on iva")
    expect(card.locator(".reason")).to_have_text(REASON)
    expect(card.locator(".cited").first).to_contain_text(
        re.compile(r"cdra\.co2_partial_pressure: [0-9.]+ mmHg \(green\) when proposed · now [0-9.]+ mmHg \(green\)")
    )
    other = alice.locator(f'#proposal-list li[data-proposal-id="{second["proposal_id"]}"]')
    other.locator("button.decline").click()
    alice.fill("#reason-input", "one swap at a time")
    alice.click("#reason-yes")
    expect(other).to_have_attribute("data-state", "declined")
    expect(other).to_contain_text("declined by alice")
    card.locator("select[name=mode]").select_option("manual")
    card.locator("button.accept").click()
    expect(alice.locator("#run-id")).to_have_text(re.compile("^iva_cdra_filter_replacement-"))
    expect(alice.locator("#connection")).to_have_attribute("data-state", "open")
    run_id = alice.locator("#run-id").inner_text()
    expect(card).to_have_attribute("data-state", "accepted")
    expect(card.locator("a")).to_have_text(f"run {run_id}")
    again = alice.request.post(
        f"{server.url}/api/proposals/{first['proposal_id']}/accept",
        data={"mode": "manual"},
        headers={"X-CSRF-Token": alice.evaluate("view.me.csrf")},
    )
    assert again.status == 409 and "accepted" in again.json()["error"], again.text()  # one acceptance, one run
    expect(alice.locator("#run-mode")).to_have_text("manual")
    expect(alice.locator("#proc-title")).to_contain_text("IVA CDRA Filter Replacement")

    # the procedure as written: numbering, notes/cautions, automatable icons, live telemetry
    expect(instruction(alice, "2.1")).to_contain_text("2.1")
    expect(alice.locator("#procedure .notice.note").first).to_contain_text("the locate that follows is its check")
    expect(alice.locator("#procedure .notice.note").nth(1)).to_contain_text("registered to the filter")
    expect(alice.locator("#procedure .notice.caution").first).to_contain_text("within reach of the CDRA cabinet")
    expect(instruction(alice, "1.3").locator(".auto-icon")).to_have_attribute("title", re.compile("PAX can run this"))
    expect(instruction(alice, "1.1").locator(".telemetry")).to_contain_text(
        re.compile(r"✓ Affordance Template Server Active = true · \d+\.\d s ago")
    )
    expect(instruction(alice, "1.1").locator(".telemetry")).to_have_attribute("data-state", "ok")
    expect_current(instruction(alice, "1.1"))

    # manual mode: the operator checks the two verifies, then Sends the first command
    instruction(alice, "1.1").locator("button.perform").click()
    expect(instruction(alice, "1.1").locator(".mark")).to_contain_text("completed by alice")
    instruction(alice, "1.2").locator("button.perform").click()
    expect_current(instruction(alice, "1.3"))
    send = instruction(alice, "1.3").locator("button.perform")
    expect(send).to_have_text("Send")
    send.click()
    expect(instruction(alice, "1.3").locator(".detail")).to_contain_text("Result: succeeded — added cdra_filter:0")
    expect(instruction(alice, "2.2").locator(".line > .text")).to_have_text(
        "Plan the grasp-and-pull trajectory for cdra_filter:0"
    )
    expect(instruction(alice, "1.3").locator(".mark")).to_contain_text("completed by alice")
    sent_row = audit_row(alice, "command_sent", "1.3", "alice")
    expect(sent_row).to_contain_text('sent Add Affordance Template "cdra_filter"')
    expect(audit_row(alice, "command_result", "1.3", "alice")).to_contain_text("succeeded: added cdra_filter:0")

    # an observer opens the same run in another browser and sees it live, without controls
    carol = sign_in("carol")
    expect(carol.locator("#start-panel")).to_be_hidden()
    expect(carol.locator(f'#proposal-list li[data-proposal-id="{first["proposal_id"]}"]')).to_contain_text(
        "accepted by alice"
    )
    expect(carol.locator("#proposal-list .proposal-answers")).to_have_count(0)  # observers answer nothing
    carol.goto(f"{server.url}/#run={run_id}")
    expect(carol.locator("#connection")).to_have_attribute("data-state", "open")
    expect(instruction(carol, "1.3").locator(".mark")).to_contain_text("completed by alice")
    expect(instruction(carol, "1.4").locator("button.perform")).to_be_disabled()
    expect(carol.locator("#mode-autonomous")).to_be_disabled()
    token = {"X-CSRF-Token": carol.evaluate("view.me.csrf")}  # her session's own token: only her role refuses it
    forced = carol.request.post(
        f"{server.url}/api/runs/{run_id}/actions", data={"action": "perform", "instruction": "1.4"}, headers=token
    )
    assert forced.status == 403, forced.text()
    assert "observer" in forced.json()["error"]
    assert (
        carol.request.post(
            f"{server.url}/api/runs", data={"procedure": IVA, "binding": "iva.yaml"}, headers=token
        ).status
        == 403
    )

    # autonomous: PAX runs on to the unlock, hazardous in the cdra SysRep: under the IVA robot
    # side's critical commanding it waits for a second operator. alice sends it for approval; she
    # is offered no Approve… of her own request, and her approval forced through the API is
    # refused and on the record; bob, at his console, approves it and PAX sends it at once
    alice.click("#mode-autonomous")
    expect(alice.locator("#run-mode")).to_have_text("autonomous")
    unlock = instruction(alice, UNLOCK)
    expect_current(unlock, timeout=MOTION_MS)
    expect(alice.locator("#hold")).to_contain_text(
        f"Hazardous command {UNLOCK}: Unlock the dirty filter in the CDRA cabinet"
    )
    send_for_approval(alice, UNLOCK)
    expect(unlock.locator("button.approve")).to_be_hidden()
    expect(unlock.locator(".approval-wait")).to_be_visible()
    expect(unlock.locator(".approval-wait")).to_have_text("waiting for another operator")
    own = alice.request.post(
        f"{server.url}/api/runs/{run_id}/actions",
        data={"action": "approve", "instruction": UNLOCK},
        headers={"X-CSRF-Token": alice.evaluate("view.me.csrf")},
    )
    assert own.status == 409, own.text()
    assert "a second operator must approve it, not alice" in own.json()["error"]
    expect(audit_row(alice, "action_refused", UNLOCK, "alice")).to_have_count(1)
    expect(audit_row(alice, "command_sent", UNLOCK, "PAX")).to_have_count(0)
    bob = sign_in("bob")
    bob.goto(f"{server.url}/#run={run_id}")
    instruction(bob, UNLOCK).locator("button.approve").click()
    expect(bob.locator("#confirm-text")).to_contain_text("alice sent it for approval")
    bob.click("#confirm-yes")
    expect(audit_row(alice, "command_sent", UNLOCK, "PAX")).to_contain_text("sent by alice, approved by bob")

    # PAX runs on and holds at the manual instruction 2.6; both browsers see it
    for page in (alice, carol):
        expect_current(instruction(page, "2.6"), timeout=MOTION_MS)
        expect(page.locator("#hold")).to_contain_text(
            "2.6: Confirm that the area in front of the CDRA cabinet is clear"
        )
    expect(instruction(alice, "2.5").locator(".mark")).to_contain_text("completed by PAX")
    expect(instruction(alice, "2.1").locator(".raw-detail")).to_contain_text("frame=cabinet/slot")
    expect(audit_row(alice, "awaiting_operator", "2.6", "PAX")).to_have_count(1)
    expect(instruction(carol, "2.6").locator("button.done")).to_be_disabled()
    instruction(alice, "2.6").scroll_into_view_if_needed()
    screenshot(alice, "web_autonomous_hold.png")
    instruction(carol, "2.6").scroll_into_view_if_needed()
    screenshot(carol, "web_observer.png")

    # Done lets PAX carry on: the arm pulls the dirty filter and places it on the rack, then PAX
    # holds at the record of the clean filter's id; the id typed in goes into the next command
    instruction(alice, "2.6").locator("button.done").click()
    expect(instruction(alice, "2.6").locator(".mark")).to_contain_text("completed by alice")
    record = instruction(alice, "4.1")
    expect_current(record, timeout=MOTION_MS)
    expect(instruction(alice, "3.5").locator(".mark")).to_contain_text("completed by PAX")
    # a label misread: an id of no clean filter on the rack is refused before the robot moves
    alice.click("#mode-manual")  # alice takes the next steps by hand
    record.locator("input.record-value").fill("CDRA-F-0021")
    record.locator("button.record").click()
    expect(record.locator(".record-error")).to_contain_text(  # next to the field, in words
        "CDRA-F-0021 is not one of the clean filters on the rack now; the CDRA Filter Bay reports CDRA-F-0012 and "
        "CDRA-F-0013"
    )
    expect_current(record)
    # a clean filter, but not the one set aside for this swap: re-entered before the arm uses it
    record.locator("input.record-value").fill("CDRA-F-0013")
    record.locator("button.record").click()
    expect(audit_row(alice, "operator_input", "4.1", "alice")).to_contain_text("clean filter id = CDRA-F-0013")
    read_slot = instruction(alice, "4.2")
    expect(read_slot.locator(".line > .text")).to_contain_text("CDRA-F-0013")
    record.locator("button.correct").click()
    expect(alice.locator("#reason-value")).to_have_value("CDRA-F-0013")
    alice.fill("#reason-value", "CDRA-F-0012")
    alice.fill("#reason-input", "0013 is kept for the next swap")
    alice.click("#reason-yes")
    expect(audit_row(alice, "record_corrected", "4.1", "alice")).to_contain_text("CDRA-F-0013 → CDRA-F-0012")
    expect(read_slot.locator(".line > .text")).to_contain_text("CDRA-F-0012")
    alice.click("#mode-autonomous")
    expect(audit_row(alice, "command_sent", "4.2", "PAX")).to_contain_text("Slot Of Filter for CDRA-F-0012")
    # and into the sub-procedure 4.3 calls, which registers the template where the drawings put it
    expect(audit_row(alice, "command_sent", "4.3/1.1", "PAX")).to_contain_text("frame: filter/CDRA-F-0012")
    confirm_slot = instruction(alice, "5.1")
    expect_current(confirm_slot, timeout=MOTION_MS)
    confirm_slot.locator("button.done").click()
    for page in (alice, carol):
        expect_ended(page, "completed", within_ms=MOTION_MS)  # the arm inserts the filter and stows first
    expect(alice.locator('#audit li[data-kind="run_completed"]')).to_have_count(1)

    # the report names both operators of the unlock
    report = alice.request.get(f"{server.url}/runs/{run_id}/report")
    assert report.status == 200, report.text()
    assert "sent Unlock Filter [hazardous] (sent by alice, approved by bob)" in report.text()

    # the audit log holds every action with its user, and nothing from the observer but her refused act
    log = AuditLog(server.database.url)
    try:
        events = log.events(run_id)
    finally:
        log.close()
    inputs = [e for e in events if e.kind.value in ("operator_input", "record_corrected")]
    assert [(e.instruction, e.actor, e.data.to_json().get("value")) for e in inputs] == [
        ("4.1", "alice", "CDRA-F-0013"),
        ("4.1", "alice", "CDRA-F-0012"),
    ]
    assert (
        inputs[1].data.to_json()["old"] == "CDRA-F-0013"
        and inputs[1].data.to_json()["reason"] == "0013 is kept for the next swap"
    )
    actors = {e.actor for e in events}
    assert actors == {"alice", "bob", "carol", "PAX"}, actors
    started = events[0].data.to_json()
    assert (events[0].actor, started["proposal"]) == (
        "alice",
        {"id": first["proposal_id"], "agent": "daphne", "reason": REASON},
    )
    assert (started["release"], started["rehearsal"]) == (1, False)

    # the agent reads what became of its proposals, and the run it started
    told: dict[str, Any] = {}

    async def follow_up(client: Client) -> None:
        told["proposals"] = (await answer(client, "list_proposals"))["proposals"]
        told["run"] = await answer(client, "explain_run", run_id=run_id)

    agent_session(server, ros_env, follow_up)
    answered = {p["proposal_id"]: p for p in told["proposals"]}
    assert (answered[first["proposal_id"]]["state"], answered[first["proposal_id"]]["run_id"]) == ("accepted", run_id)
    assert answered[first["proposal_id"]]["answered_by"] == "alice"
    assert (answered[second["proposal_id"]]["state"], answered[second["proposal_id"]]["answer"]) == (
        "declined",
        "one swap at a time",
    )
    assert told["run"]["outcome"] == "completed" and told["run"]["started_by"] == "alice"
    refused = [(e.actor, e.instruction, e.data.to_json()) for e in events if e.kind.value == "action_refused"]
    assert [(actor, number, d["action"], d["rule"]) for actor, number, d in refused] == [
        ("carol", "1.4", "perform", "observers_watch"),
        ("alice", UNLOCK, "approve", "two_person"),
        ("alice", "4.1", "enter", "run_state"),  # the id of no clean filter on the rack
    ]
    approvals = [
        (e.kind.value, e.actor) for e in events if e.instruction == UNLOCK and e.kind.value.startswith("approval")
    ]
    assert approvals == [("approval_requested", "alice"), ("approval_given", "bob")]
    unlocked = next(e.data.to_json() for e in events if e.kind.value == "command_sent" and e.instruction == UNLOCK)
    assert (unlocked["requested_by"], unlocked["approved_by"]) == ("alice", "bob")
    sent = [e for e in events if e.kind.value == "command_sent" and e.instruction == "1.3"]
    assert [e.actor for e in sent] == ["alice"] and sent[0].data.to_json()["args"][
        "affordance_template"
    ] == "cdra_filter"
