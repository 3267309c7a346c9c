"""`caretaker report RUN`: HTML and Markdown with every step, who did what, telemetry, timeline, images."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from lxml import etree

from pride.executive import Executive, Hold, Mode, RunStatus
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog
from support.audit import AuditDatabase
from support.lab_gateway import LabGateway
from support.procedures import FIXTURES, REPO
from support.processes import COMMAND_HANG_S


def _complete_run(tmp_path: Path, sysreps: dict[str, SysRep], db: str) -> tuple[str, str]:
    log = AuditLog(db)
    executive = Executive(
        check_procedure(FIXTURES / "lab_all_kinds.xml", sysreps),
        LabGateway(str(tmp_path / "images")),
        log,
        run_id="report-run",
        mode=Mode.AUTONOMOUS,
    )
    executive.start("alice")
    answers = {
        Hold.OPERATOR_INPUT: lambda: executive.enter("alice", "dock"),
        Hold.CONFIRMATION: lambda: executive.confirm("bob"),
        Hold.OPERATOR_ACTION: lambda: executive.mark_done("bob"),
    }
    while True:
        snap = executive.wait_for(lambda s: s.hold is not None or s.status is not RunStatus.ACTIVE, 20)
        assert snap is not None
        if snap.status is not RunStatus.ACTIVE:
            break
        answers[snap.hold]()
    executive.join(20)
    log.close()
    assert snap.status is RunStatus.COMPLETED
    return db, "report-run"


def report(run_id: str, db: str, *options: str) -> subprocess.CompletedProcess[str]:
    """``caretaker report`` with the lab bench's SysReps beside the shipped ones (their labels)."""
    sysreps = ["--sysrep-dir", str(REPO / "sysrep"), "--sysrep-dir", str(FIXTURES / "sysrep")]
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "report", run_id, "--db", db, *sysreps, *options],
        capture_output=True,
        text=True,
        timeout=COMMAND_HANG_S,
    )


def test_report_shows_every_step_actor_value_timeline_and_image(
    tmp_path: Path, sysreps: dict[str, SysRep], database: AuditDatabase
) -> None:
    db, run_id = _complete_run(tmp_path, sysreps, database.url)
    out = tmp_path / "reports"
    proc = report(run_id, db, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    html_path, md_path = (Path(p) for p in proc.stdout.split())
    html_text, markdown = html_path.read_text(), md_path.read_text()
    for title in ("Prepare the bench", "Inspect", "Recover", "Finish", "Done"):
        assert title in html_text and title in markdown
    assert "| 3 | Recover | not reached |" in markdown
    rows = {line.split(" | ")[1]: line for line in markdown.splitlines() if line.startswith("| ") and " | " in line}
    assert rows["Prepare the bench"].endswith("| 4 | 0 | 0 | PAX, alice |")
    assert rows["Inspect"].endswith("| 6 | 0 | 0 | PAX, bob |")
    assert "recorded target = dock" in html_text and "'dock'" not in html_text
    assert "| Door Open | `true` | is true | ok |" in markdown  # the SysRep's label, the condition in words
    assert "| Temperature | `21.5 degC` | is 21 ± 1 degC | ok |" in markdown
    # 1.3 and 2.1 have no text of their own: they read as the procedure view words them
    assert "started: Move for dock (speed: 0.5)" in markdown and "sent Move for dock (speed: 0.5)" in markdown
    assert "confirmed the hazardous command: Vent Chamber" in markdown
    assert "sent Vent Chamber [hazardous]" in markdown
    assert "lab.move(" not in markdown + html_text  # the call only in a raw report
    assert "**completed**" in markdown
    assert f"- Audit chain: run {run_id}: chain of " in markdown and " events intact; head " in markdown

    document = etree.HTML(html_text)
    svg = document.find(".//svg")
    assert svg is not None and len(svg.findall("rect")) >= 4  # one bar per visited step
    images = document.findall(".//img")
    assert len(images) == 1
    copied = html_path.parent / images[0].get("src")
    assert copied.read_bytes().startswith(b"\x89PNG")
    assert f"![dock_view]({images[0].get('src')})" in markdown
    assert (out / f"{run_id}-timeline.svg").read_text().startswith("<svg")

    raw = report(run_id, db, "--out", str(tmp_path / "raw"), "--raw")
    assert raw.returncode == 0, raw.stderr
    raw_markdown = Path(raw.stdout.split()[1]).read_text()
    assert "sent Move for dock (speed: 0.5) · raw: lab.move(target=dock, speed=0.5)" in raw_markdown


def test_report_of_an_unknown_run_fails_clearly(tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "caretaker.cli",
            "report",
            "nope",
            "--db",
            f"sqlite:///{tmp_path}/a.db",
            "--out",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=COMMAND_HANG_S,
    )
    assert proc.returncode == 2
    assert "no run 'nope'" in proc.stderr


def test_report_of_an_edited_run_says_so_and_verify_names_the_event(
    tmp_path: Path, sysreps: dict[str, SysRep], database: AuditDatabase
) -> None:
    db, run_id = _complete_run(tmp_path, sysreps, database.url)
    assert report(run_id, db, "--verify").returncode == 0
    database.tamper(
        "UPDATE audit_records SET data = replace(data, 'dock', 'bay') WHERE kind = 'operator_input'"
    )  # someone "corrects" the recorded value
    log = AuditLog(db)
    try:
        seq = next(e.seq for e in log.events(run_id) if e.data.to_json().get("value") == "bay")
    finally:
        log.close()

    verify = report(run_id, db, "--verify")
    assert verify.returncode == 1
    assert f"event {seq} (operator_input at 1.2) was changed after it was written" in verify.stderr

    written = report(run_id, db, "--out", str(tmp_path / "reports"))
    assert written.returncode == 1 and "WARNING" in written.stderr
    markdown = Path(written.stdout.split()[1]).read_text()
    assert f"- Audit chain: run {run_id}: event {seq} (operator_input at 1.2) was changed" in markdown


def test_an_event_edited_into_data_that_does_not_fit_its_kind_is_named_not_a_traceback(
    tmp_path: Path, sysreps: dict[str, SysRep], database: AuditDatabase
) -> None:
    db, run_id = _complete_run(tmp_path, sysreps, database.url)
    database.tamper(
        'UPDATE audit_records SET data = replace(data, \'"name": "\', \'"name": 7, "was": "\') '
        "WHERE kind = 'operator_input'"
    )  # a record's name made a number: no operator_input can hold that
    written = report(run_id, db, "--out", str(tmp_path / "reports"))
    assert written.returncode == 1 and "Traceback" not in written.stderr
    assert f"run {run_id}, event " in written.stderr
    assert "operator_input: data.name must be text, not int" in written.stderr
    assert "was changed after it was written" in written.stderr  # and what its chain says
