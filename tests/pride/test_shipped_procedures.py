"""The shipped procedures complete in autonomous mode against the real robot side.

Each test brings up the scene's robot side (simulation, planner, AT server, rosbridge: separate
processes), runs ``caretaker run`` with its JVM-hosted PAX plugins exactly as an operator would,
unattended (recorded answers given with --set/--confirm-manual), then checks the audit log and the
after-action report.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from pride.audit_log import AuditLog
from pride.events import EventKind
from pride.parser import load_procedure
from support.procedures import REPO
from support.stack import robot_parts

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=90)]

SCENES = {
    "iva": ("iva_cdra_filter_replacement.xml", ["--set", "clean_filter_id=CDRA-F-0012"]),
    "eva": ("eva_inspection.xml", ["--set", "damage=false"]),
}


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_shipped_procedure_completes_autonomously_and_the_report_shows_every_step(
    scene: str, ros_env: dict[str, str], tmp_path: Path
) -> None:
    procedure_file, answers = SCENES[scene]
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    # the robot side of the shipped deployment, each part its own process as `caretaker up` starts them
    with robot_parts(scene, ros_env) as stack:
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "caretaker.cli",
                "run",
                str(REPO / "procedures" / procedure_file),
                "--binding",
                str(REPO / "sysrep" / "bindings" / f"{scene}.yaml"),
                "--rosbridge",
                stack.bridge_url,
                "--auto",
                "--user",
                "tester",
                "--db",
                db,
                *answers,
                "--confirm-manual",
                "--rehearsal",  # the shipped procedure as it is (a draft in this new database), on the simulator
            ],
            env=ros_env,
            capture_output=True,
            text=True,
            timeout=600,
            stdin=subprocess.DEVNULL,
        )
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]

    log = AuditLog(db)
    try:
        ((run_id, _, _),) = log.runs()
        events = log.events(run_id)
    finally:
        log.close()
    assert events[-1].kind is EventKind.RUN_COMPLETED
    procedure = load_procedure(REPO / "procedures" / procedure_file)
    nominal = [s for s in procedure.steps if not s.contingency]
    completed = {e.instruction for e in events if e.kind is EventKind.INSTRUCTION_COMPLETED}
    for step in nominal:
        assert {i.number for i in step.instructions} <= completed, f"step {step.number} not completed"
    plan_checks = [e for e in events if e.kind is EventKind.TELEMETRY_SEEN and e.data["item"] == "plan_valid"]
    assert plan_checks and all(e.data["value"] is True for e in plan_checks if e.data["ok"])
    assert all(
        e.data["success"]
        for e in events
        if e.kind is EventKind.COMMAND_RESULT and e.data["command"] != "plan_trajectory"
    )  # a failed plan may only have branched

    report = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "report", run_id, "--db", db, "--out", str(tmp_path / "reports")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert report.returncode == 0, report.stderr
    markdown = Path(report.stdout.split()[1]).read_text()
    for step in nominal:
        row = next(line for line in markdown.splitlines() if line.startswith(f"| {step.number} | {step.title} |"))
        assert "not reached" not in row
    if scene == "eva":
        captured = re.findall(r"!\[[^\]]*(hull_[a-d])[^\]]*\]\(([^)]+)\)", markdown)
        assert sorted(target for target, _ in captured) == ["hull_a", "hull_b", "hull_c", "hull_d"]
        for _, image in captured:  # copied next to the report, real PNGs
            assert (tmp_path / "reports" / image).read_bytes().startswith(b"\x89PNG")
