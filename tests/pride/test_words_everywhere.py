"""The report and the terminal read as the procedure view does: words, rounded values, no code.

The shipped IVA procedure runs on the real executive against a run recorded on the real robot
side (support/recorded_run.py: the planner's own noisy poses, the AT server's answers), with the
runner's terminal printer listening; its report is written from the audit log as stored. Neither
may show a ``${...}``, a call (``affordance_templates.…(…)``) or a number with more than four
decimals; with the raw switch the calls are there, in full. A refused record says why in words.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest

from caretaker.terminal import ProgressPrinter, TerminalLines
from pride.approvals import ApprovalPolicy, CriticalLevel
from pride.events import Event
from pride.executive import Executive, Hold, Mode, OperatorActionError, RunStatus
from pride.phrasing import Wording
from pride.report import write_report
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog
from support.executive_runs import finished, held
from support.procedures import REPO
from support.recorded_run import RecordedSystems, recorded_events

IVA = REPO / "procedures" / "iva_cdra_filter_replacement.xml"
#: A number shown to more decimals than anyone can use (0.14999985294229648, 1.5707959999869179).
LONG_NUMBER = re.compile(r"\d+\.\d{5,}")


def _no_code(text: str) -> None:
    assert "${" not in text
    assert "affordance_templates." not in text and "cdra." not in text  # no call, no system.item
    assert not LONG_NUMBER.search(text), LONG_NUMBER.search(text)


def _reports(events: list[Event], out: Path, wording: Wording) -> str:
    html_path, md_path = write_report(events, out, wording=wording)
    return html_path.read_text() + md_path.read_text() + (out / f"{events[0].run_id}-timeline.svg").read_text()


def _printed(events: list[Event], wording: Wording) -> str:
    """What the runner's terminal printed for these events (its printer is a listener of the run)."""
    out = io.StringIO()
    printer = ProgressPrinter(check_procedure(IVA, wording.sysreps).procedure, TerminalLines(out), wording)
    for event in events:
        printer(event)
    return out.getvalue()


@pytest.fixture
def replayed(tmp_path: Path, sysreps: dict[str, SysRep]) -> tuple[list[Event], str, list[str]]:
    """The IVA procedure run again on the recording: its stored events, the terminal's lines, and
    what refusing a record said."""
    log = AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")
    executive = Executive(
        check_procedure(IVA, sysreps),
        RecordedSystems(recorded_events()),
        log,
        run_id="iva-words",
        mode=Mode.AUTONOMOUS,
        approvals=ApprovalPolicy(CriticalLevel.HAZARDOUS),  # the IVA deployment's: the unlock waits for bob
    )
    terminal = io.StringIO()
    executive.add_listener(ProgressPrinter(executive.procedure, TerminalLines(terminal), Wording(sysreps)))
    refusals = []
    executive.start("tester")
    held(executive, Hold.CONFIRMATION, "2.4")
    executive.confirm("tester")
    held(executive, Hold.APPROVAL, "2.4")
    executive.approve("bob")
    held(executive, Hold.OPERATOR_ACTION, "2.6")
    executive.mark_done("tester")
    held(executive, Hold.OPERATOR_INPUT, "4.1")
    with pytest.raises(OperatorActionError) as refused:
        executive.enter("tester", "CDRA-F-9999")  # a label misread: no such clean filter on the rack
    refusals.append(str(refused.value))
    executive.enter("tester", "CDRA-F-0012")
    held(executive, Hold.OPERATOR_ACTION, "5.1")
    executive.mark_done("tester")
    assert finished(executive).status is RunStatus.COMPLETED
    executive.join(20)
    try:
        events = log.events("iva-words")
    finally:
        log.close()
    return events, terminal.getvalue(), refusals


def test_the_iva_run_reads_in_words_in_the_report_and_on_the_terminal(
    replayed: tuple[list[Event], str, list[str]], sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    events, printed, refusals = replayed
    report = _reports(events, tmp_path / "reports", Wording(sysreps))
    for text in (report, printed):
        _no_code(text)
        # a sent command reads as the procedure view's sentence, with the values it was sent with
        assert (
            'sent Set Display Object Pose "cdra_filter" for cdra_filter:0 '
            "(id: 0, frame: filter/CDRA-F-0012, position 0 mm, orientation 0°)" in text
        )
        assert 'sent Plan Trajectory "grasp_and_pull" for cdra_filter:0' in text
        assert "sent Unlock Filter [hazardous] (sent by tester, approved by bob)" in text
        # the planner's end pose, in millimetres and degrees, in its frame
        assert "end pose position (162, 335, 628) mm, orientation (-105, 0, 10)° in robot_base" in text  # look_above
        # a called sub-procedure's sentence, with the values its caller passed (the recorded id among them)
        assert (
            "Register the CDRA filter AT at clean filter CDRA-F-0012 where the drawings put it, to look at rack/slot_1"
            in text
        )
    assert "saw Plan Valid = true ✓" in report and "recorded clean filter id = CDRA-F-0012" in report
    assert "| Filter Locked | `false` | is false | ok |" in report  # verified telemetry, by its label
    assert "  2.5                 Filter Locked = false" in printed
    assert refusals == [
        "CDRA-F-9999 is not one of the clean filters on the rack now; the CDRA Filter Bay reports "
        "CDRA-F-0012 and CDRA-F-0013"
    ]


def test_the_raw_switch_shows_every_call_as_sent(
    replayed: tuple[list[Event], str, list[str]], sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    events, _, _ = replayed
    raw = Wording(sysreps, raw=True)
    for text in (_reports(events, tmp_path / "raw", raw), _printed(events, raw)):
        assert (
            "· raw: affordance_templates.set_display_object_pose(affordance_template=cdra_filter:0, id=0, "
            "display_object=cdra_filter, frame=cabinet/slot, x=0.0, y=0.0, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)"
        ) in text
        assert "· raw: cdra.unlock_filter()" in text
        assert "${" not in text


def test_a_run_recorded_before_the_words_reads_in_words_too(sysreps: dict[str, SysRep], tmp_path: Path) -> None:
    # the recording's log as it was written then: the report and the terminal word it the same way
    events = recorded_events()
    report, printed = _reports(events, tmp_path / "reports", Wording(sysreps)), _printed(events, Wording(sysreps))
    for text in (report, printed):
        _no_code(text)
        assert "end pose position (450, 350, 350) mm, orientation (0, 90, 45)° in robot_base" in text
