"""An agent reads a real robot's telemetry: ``read_telemetry`` through ``caretaker agent`` over
stdio, the IVA stack (``caretaker up``) reached through its binding's PAX host (a real JVM and
rosbridge), the cabin's CO2 from the simulator with its state against the SysRep's limits; how
a value is placed against its limits, in the answer's words; and how the procedure that answers an
item out of its limits is found among the listed ones."""

from __future__ import annotations

import asyncio
import sys
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from mcp import Client, StdioServerParameters

from agent.agent_audit import AgentRecords
from agent.agent_desk import ProcedureFacts, TelemetryFacts
from agent.answers import procedure_entry, telemetry_entry
from agent.mcp_server import TOKEN_ENV
from console.accounts import AccountStore
from pride.run_setup import load_sysreps
from procedure_language.lint import check_procedure
from records.agent_tokens import TokenStore
from records.audit_log import AuditLog
from support.procedures import REPO
from support.stack import stack_up
from support.web_server import new_ground_database

CARETAKER = Path(sys.executable).with_name("caretaker")
SYSREPS = load_sysreps([REPO / "sysrep"])
CO2 = next(item for item in SYSREPS["cdra"].telemetry if item.id == "co2_partial_pressure")


@pytest.mark.parametrize(
    ("value", "state", "limit"),
    [(2.5, "green", None), (4.4, "yellow", "yellow above 4"), (5.6, "red", "red above 5.3"), (None, "no value", None)],
)
def test_a_value_is_placed_against_its_limits(value: float | None, state: str, limit: str | None) -> None:
    entry = telemetry_entry(TelemetryFacts("cdra", CO2, value, None if value is None else 0.4, stale=False))
    assert (entry.state, entry.limit, entry.units) == (state, limit, "mmHg")


def test_the_procedure_that_answers_an_item_out_of_limits_says_so_in_its_listing() -> None:
    high = telemetry_entry(TelemetryFacts("cdra", CO2, 4.4, 0.4, stale=False))  # yellow, as read_telemetry says
    answering = {}
    for name in ("iva_cdra_filter_replacement.xml", "eva_inspection.xml"):
        checked = check_procedure(REPO / "procedures" / name, SYSREPS)
        entry = procedure_entry(ProcedureFacts(name, checked, "0" * 64, 1, "bob"))  # as list_procedures lists it
        answering[name] = [(r.state, r.text) for r in entry.responds_to if (r.system, r.item) == ("cdra", high.item)]
    assert answering["eva_inspection.xml"] == []
    [(state, text)] = answering["iva_cdra_filter_replacement.xml"]
    assert state == "yellow" == high.state  # yellow or worse: this reading calls for it
    assert "the filter locked in the CDRA cabinet is saturated" in text


@pytest.mark.ros
@pytest.mark.slow(seconds=60)
def test_an_agent_reads_the_iva_robots_telemetry_and_the_cabins_co2_against_its_limits(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    database = new_ground_database("sqlite", tmp_path)
    accounts = AccountStore(database.owner_url)
    try:
        accounts.add("daphne", "agent", None)
        token = TokenStore(accounts.engine).issue("daphne", timedelta(hours=1)).token
    finally:
        accounts.close()
    with stack_up(REPO / "deployments" / "iva.yaml", ros_env) as stack:
        server = StdioServerParameters(  # the robot where the stack serves it, as for caretaker serve
            command=str(CARETAKER),
            args=["agent", "--db", database.url, "--rosbridge", f"iva.yaml={stack.url}"],
            env={**ros_env, TOKEN_ENV: token},
        )
        read: dict[str, Any] = {}

        async def scenario() -> None:
            async with Client(server) as client:
                while True:  # the PAX host connects and subscribes at the first ask; its values follow
                    answer = (await client.call_tool("read_telemetry", {"robot": "iva"})).structured_content
                    assert answer is not None
                    items = {f"{i['system']}.{i['item']}": i for i in answer["items"]}
                    if items["cdra.co2_partial_pressure"]["value"] is not None:
                        break
                    await asyncio.sleep(0.5)  # nothing to await across MCP: ask again, within the call budget
                read.update(answer=answer, items=items)
                unknown = await client.call_tool("read_telemetry", {"robot": "hal9000"})
                read["unknown"] = unknown.content[0].text  # type: ignore[union-attr]

        asyncio.run(asyncio.wait_for(scenario(), 120))
    co2 = read["items"]["cdra.co2_partial_pressure"]
    assert 2.0 <= co2["value"] <= 3.0 and co2["units"] == "mmHg", co2  # the cabin as the ISS keeps it
    assert (co2["state"], co2["limit"]) == ("green", None)
    assert read["items"]["cdra.filter_locked"]["value"] is True  # the dirty filter is locked in its cabinet
    assert read["answer"]["out_of_limits"] == []
    assert "refused by rule known_robot" in read["unknown"]
    log = AuditLog(database.url)
    try:
        records = AgentRecords(log.engine)
        assert records.verify("daphne").ok
        tools = [(r.kind, r.instruction) for r in records.records("daphne")]
    finally:
        log.close()
    assert tools[-1] == ("refused", "read_telemetry") and ("answered", "read_telemetry") in tools
