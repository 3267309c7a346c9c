"""The paper's two demonstrations complete end to end, and the world ends as the procedure says.

Each runs ``caretaker demo`` exactly as the README tells a newcomer (simulation as fast as
possible): separate processes for the simulation, planner, AT server, rosbridge and the
procedure runner with its JVM; the IVA unlock, hazardous, is sent only once the demo's second
operator approved it, and its record and report name both. ``caretaker demo`` exits 0 only if
the procedure completed AND its own checks of the world hold (the deployment's ``demo.checks``,
measured by the simulation), so these tests also read what it verified: one line per check. The undisplaced runs are the
shipped procedures' autonomous runs: their audit log must show every nominal step completed and
the report every step reached.

Both also run on displaced worlds: test_displaced_demos.py.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from caretaker.demo import DEMO_APPROVER, DEMO_USER
from caretaker.processes import REPO
from pride.events import EventKind
from procedure_language.parser import load_procedure
from support.demos import demo_events, run_demo, verified

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=120), pytest.mark.timeout(900)]


def _reports(output: list[str]) -> list[Path]:
    return [Path(line.split("report: ", 1)[1]) for line in output if line.strip().startswith("report: ")]


def _every_step_done_and_reported(procedure_file: str, tmp_path: Path, output: list[str]) -> str:
    """The run's audit log has every nominal step's instructions completed, every plan check valid
    and every command but a plan succeeded; the report shows each nominal step reached. Its markdown."""
    events = demo_events(tmp_path)
    assert events[-1].kind is EventKind.RUN_COMPLETED
    nominal = [s for s in load_procedure(REPO / "procedures" / procedure_file).steps if not s.contingency]
    completed = {e.instruction for e in events if e.kind is EventKind.INSTRUCTION_COMPLETED}
    for step in nominal:
        assert {i.number for i in step.instructions} <= completed, f"step {step.number} not completed"
    plan_checks = [e for e in events if e.kind is EventKind.TELEMETRY_SEEN and e.data.to_json()["item"] == "plan_valid"]
    assert plan_checks and all(e.data.to_json()["value"] is True for e in plan_checks if e.data.to_json()["ok"])
    failed = [
        e.data
        for e in events
        if e.kind is EventKind.COMMAND_RESULT
        and e.data.to_json()["command"] != "plan_trajectory"
        and not e.data.to_json()["success"]
    ]
    assert not failed, failed  # a failed plan may only have branched
    reports = _reports(output)
    assert any(r.suffix == ".html" and r.is_file() for r in reports), output[-10:]
    markdown = next(r for r in reports if r.suffix == ".md").read_text()
    for step in nominal:
        row = next(line for line in markdown.splitlines() if line.startswith(f"| {step.number} | {step.title} |"))
        assert "not reached" not in row
    return markdown


def test_iva_cdra_filter_replacement(tmp_path: Path, ros_env: dict[str, str]) -> None:
    output = run_demo("iva", tmp_path, ros_env)
    checks = verified(output)
    assert len(checks) == 3, output[-30:]
    assert checks[0].startswith("verified: filter/CDRA-F-0007 is at rack/slot_3: "), checks
    assert checks[0].endswith(" mm from it (within 30 mm)"), checks
    assert checks[1:] == [
        "verified: /cdra/installed_filter_id is 'CDRA-F-0012'",
        "verified: /cdra/filter_locked is True",
    ]
    markdown = _every_step_done_and_reported("iva_cdra_filter_replacement.xml", tmp_path, output)
    # the unlock is hazardous: the demo's operator sent it for approval, its second operator approved it
    unlock = [
        e.data.to_json() for e in demo_events(tmp_path) if e.kind is EventKind.COMMAND_SENT and e.instruction == "2.4"
    ]
    assert [(d["command"], d["requested_by"], d["approved_by"]) for d in unlock] == [
        ("unlock_filter", DEMO_USER, DEMO_APPROVER)
    ]
    assert f"sent Unlock Filter [hazardous] (sent by {DEMO_USER}, approved by {DEMO_APPROVER})" in markdown


def test_eva_inspection(tmp_path: Path, ros_env: dict[str, str]) -> None:
    output = run_demo("eva", tmp_path, ros_env)
    checks = verified(output)
    assert checks == ["verified: images of hull_a, hull_b, hull_c, hull_d captured (4 non-empty files)"], output[-30:]
    markdown = _every_step_done_and_reported("eva_inspection.xml", tmp_path, output)
    captured = re.findall(r"!\[[^\]]*(hull_[a-d])[^\]]*\]\(([^)]+)\)", markdown)
    assert sorted(target for target, _ in captured) == ["hull_a", "hull_b", "hull_c", "hull_d"]
    for _, image in captured:  # copied next to the report, real PNGs
        assert (tmp_path / "reports" / image).read_bytes().startswith(b"\x89PNG")
