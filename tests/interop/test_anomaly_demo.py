"""``caretaker demo anomaly`` closes the loop, as the README tells a newcomer to run it.

The IVA habitat (its onboard executive behind ``caretaker link`` at 1.3 s one way, wss:// and
the link's secret), a console on a ground database and the reference agent (``caretaker agent
--reference``, an MCP client of ``caretaker agent``), all real processes. The demo raises the
cabin's CO2; the agent's alarm, diagnosis and proposal, the demo operator's one acceptance, the
habitat's run and the CO2 back within its limits must all happen, in that order, and the world
must end as the IVA demo's checks say. The record must name the proposal and the agent.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from agent.agent_audit import AgentRecords
from caretaker.anomaly_demo import WITHIN_S
from caretaker.processes import caretaker
from records.agent_proposals import ProposalStore
from records.audit_log import AuditLog

#: What the demo may take besides its loop: starting the habitat, the console and the agent, stopping them.
STARTING_S = 600.0
pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=150), pytest.mark.timeout(WITHIN_S + STARTING_S + 60)]

EVENTS = ["alarm", "proposal", "acceptance", "start", "completion", "cleared"]


def test_the_anomaly_demo_answers_the_co2_alarm_from_proposal_to_cleared(
    tmp_path: Path, ros_env: dict[str, str]
) -> None:
    demo = caretaker("demo", "anomaly", "--reports", str(tmp_path), env=ros_env, name="demo-anomaly")
    try:
        # The demo gives its loop WITHIN_S and says where it stopped; its habitat, console and agent
        # starting take the rest. A crowded machine stretches all of it, so only a hang fails here.
        demo.proc.wait(timeout=WITHIN_S + STARTING_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"caretaker demo anomaly still running after {WITHIN_S + STARTING_S:.0f} s:\n{demo.tail()}")
    finally:
        demo.stop()
    output = list(demo.output)
    # the demo's own lines last: a long log is shown cut in its middle
    own = [line for line in output if line.startswith(("caretaker demo anomaly:", "  verified", "  WRONG"))]
    assert demo.proc.returncode == 0, "\n".join(output[-60:] + ["the demo said:", *own])
    told = [re.match(r"\s+agent: (\w+) (\S+) (.*)", line) for line in output]
    heard = [(m[1], m[3]) for m in told if m]
    assert [event for event, _ in heard if event in EVENTS] == EVENTS, heard
    alarm = dict(heard)["alarm"]
    assert re.fullmatch(r"cdra\.co2_partial_pressure = 4\.\d+ mmHg is yellow above 4", alarm), alarm
    cleared = re.fullmatch(r"cdra\.co2_partial_pressure = ([\d.]+) mmHg is within its limits", dict(heard)["cleared"])
    assert cleared is not None and float(cleared[1]) <= 4.0, dict(heard)["cleared"]
    offsets = [
        float(line.split()[0]) for line in output if re.fullmatch(r"\s+[\d.]+\s+(" + "|".join(EVENTS) + ")", line)
    ]
    assert len(offsets) == 6 and offsets == sorted(offsets), output[-20:]
    checks = [line.strip() for line in output if line.strip().startswith(("verified", "WRONG"))]
    assert len(checks) == 3 and checks[0].startswith("verified: filter/CDRA-F-0007 is at rack/slot_3: "), checks
    assert checks[1:] == [
        "verified: /cdra/installed_filter_id is 'CDRA-F-0012'",
        "verified: /cdra/filter_locked is True",
    ]
    assert any("operator actions: 1 (the acceptance)" in line for line in output)

    [database] = tmp_path.glob("*/ground.db")
    log = AuditLog(f"sqlite:///{database}")
    try:
        [proposal] = ProposalStore(log.engine).proposals()
        assert (proposal.state, proposal.closed_by, proposal.proposed.agent) == ("accepted", "demo", "daphne")
        assert proposal.proposed.inputs == {"clean_filter_id": "CDRA-F-0012"}
        assert [c.item for c in proposal.proposed.cited] == ["co2_partial_pressure", "clean_filter_ids"]
        events = log.events(str(proposal.run_id))
        started = events[0].data.to_json()
        assert started["proposal"] == {"id": proposal.id, "agent": "daphne", "reason": proposal.proposed.reason}
        assert events[-1].kind.value == "run_completed"
        assert AgentRecords(log.engine).verify("daphne").ok
    finally:
        log.close()
