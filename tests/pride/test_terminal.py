"""The runner's terminal console: prompts an operator at a TTY, answers unattended runs from options."""

from __future__ import annotations

import contextlib
import io
import itertools
import os
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from caretaker import terminal as terminal_module
from caretaker.terminal import OperatorConsole, ProgressPrinter, TerminalLines, Unattended
from pride.events import EventKind
from pride.executive import Executive, Mode, RunStatus, Snapshot
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog
from support.audit import RecordedJournal
from support.lab_gateway import LabGateway
from support.procedures import FIXTURES


def _executive(
    sysreps: dict[str, SysRep], tmp_path: Path, mode: Mode, procedure: str = "lab_all_kinds.xml"
) -> tuple[Executive, RecordedJournal, LabGateway]:
    journal, gateway = RecordedJournal(AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")), LabGateway(str(tmp_path))
    executive = Executive(check_procedure(FIXTURES / procedure, sysreps), gateway, journal, run_id="t", mode=mode)
    return executive, journal, gateway


def test_operator_at_a_terminal_runs_a_manual_procedure_through_prompts(
    sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    executive, journal, gateway = _executive(sysreps, tmp_path, Mode.MANUAL)
    out = io.StringIO()
    terminal = TerminalLines(out)
    executive.add_listener(ProgressPrinter(executive.procedure, terminal))
    prompts: list[str] = []
    # Enter = perform; the record gets "dock" (after a refused value); y confirms the hazard
    answers = itertools.chain(["", "garage", "dock", "", "", "y"], itertools.repeat(""))

    def read(prompt: str) -> str:
        prompts.append(prompt)
        return next(answers)

    executive.start("pat")
    final = OperatorConsole(executive, "pat", Unattended(), interactive=True, out=terminal, read=read).run()
    assert final.status is RunStatus.COMPLETED, out.getvalue()
    assert any("Where should the arm go? (string) >" in p for p in prompts)
    assert any("hazardous; confirm, then send" in p and "[y] confirm and send" in p for p in prompts)
    assert "not accepted: target: 'garage' is not one of ['dock', 'shelf']" in out.getvalue()
    assert "CAUTION: The chamber vents to vacuum." in out.getvalue()
    assert "Step 4  Finish" in out.getvalue()
    assert {e.actor for e in journal.events if e.kind is EventKind.COMMAND_SENT} == {"pat"}


def test_unattended_console_answers_from_options_and_stops_where_it_has_none(
    sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    executive, journal, gateway = _executive(sysreps, tmp_path, Mode.AUTONOMOUS)
    out = io.StringIO()
    executive.start("quinn")

    def no_terminal(prompt: str) -> str:
        raise AssertionError(f"prompted without a terminal: {prompt}")

    final = OperatorConsole(
        executive,
        "quinn",
        Unattended({"target": "dock"}, confirm_manual=True),
        interactive=False,
        out=TerminalLines(out),
        read=no_terminal,
    ).run()
    assert final.status is RunStatus.STOPPED
    assert "pass --confirm-hazardous to confirm hazardous commands" in out.getvalue()
    assert [c for _, c, _ in gateway.sent] == ["move"]
    stopped = journal.events[-1]
    assert (
        stopped.kind is EventKind.RUN_STOPPED and stopped.actor == "quinn" and "2.1" in stopped.data.to_json()["reason"]
    )


@pytest.mark.parametrize("reason, recorded", [("end of shift", "end of shift"), ("", "stopped at the terminal")])
def test_operator_can_stop_from_the_prompt_saying_why(
    sysreps: dict[str, SysRep], tmp_path: Path, reason: str, recorded: str
) -> None:
    executive, journal, gateway = _executive(sysreps, tmp_path, Mode.MANUAL)
    executive.start("rita")
    answers = iter(["q", reason])
    final = OperatorConsole(
        executive,
        "rita",
        Unattended(),
        interactive=True,
        out=TerminalLines(io.StringIO()),
        read=lambda prompt: next(answers),
    ).run()
    assert final.status is RunStatus.STOPPED
    assert (journal.events[-1].actor, journal.events[-1].data.to_json()["reason"]) == ("rita", recorded)


class _Heard(TerminalLines):
    """Terminal lines that tell a test when a line containing ``awaited`` was said."""

    def __init__(self, awaited: str) -> None:
        super().__init__(io.StringIO())
        self.awaited = awaited
        self.heard = threading.Event()

    def say(self, text: str) -> None:
        super().say(text)
        if self.awaited in text:
            self.heard.set()


@contextlib.contextmanager
def _unattended_waiting_for_a_report(
    executive: Executive,
) -> Iterator[tuple[_Heard, list[Snapshot], threading.Thread]]:
    """The run started, an unattended terminal answering dock=shelf on a thread of its own, once it
    waits for a report: (what it said, its final snapshot once it returned, its thread); joined after."""
    out = _Heard("waiting up to")
    console = OperatorConsole(executive, "quinn", Unattended({"dock": "shelf"}), interactive=False, out=out)
    executive.start("quinn")
    finals: list[Snapshot] = []
    running = threading.Thread(target=lambda: finals.append(console.run()))
    running.start()
    try:
        assert out.heard.wait(30), out.stream.getvalue()
        yield out, finals, running
    finally:
        running.join(30)


def test_unattended_answer_refused_for_a_stale_report_is_given_again_once_the_system_reports(
    sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    # after a lost link or a restarted bridge the list a record is checked against is stale until
    # it crosses the link again: an unattended run waits for it, it does not stop
    executive, journal, gateway = _executive(sysreps, tmp_path, Mode.AUTONOMOUS, "lab_records.xml")
    gateway.stale.add("docks")
    gateway.values["state"] = "shelf"
    with _unattended_waiting_for_a_report(executive) as (out, finals, _):
        gateway.stale.discard("docks")
        gateway.set("docks", "dock, shelf")  # the report comes again: the listener wakes the wait
    said = out.stream.getvalue()
    assert [final.status for final in finals] == [RunStatus.COMPLETED], said
    assert "shelf cannot be checked now: the last report of the" in said and "is stale" in said
    entered = [e for e in journal.events if e.kind is EventKind.OPERATOR_INPUT]
    assert [(e.data.to_json()["value"], e.data.to_json()["checked_against"]) for e in entered] == [
        ("shelf", "lab.docks")
    ]


def test_unattended_answer_stops_the_run_when_the_report_never_comes(
    sysreps: dict[str, SysRep], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(terminal_module, "REPORT_WAIT_S", 0.2)
    executive, journal, gateway = _executive(sysreps, tmp_path, Mode.AUTONOMOUS, "lab_records.xml")
    gateway.stale.add("docks")
    executive.start("quinn")
    out = io.StringIO()
    final = OperatorConsole(
        executive, "quinn", Unattended({"dock": "shelf"}), interactive=False, out=TerminalLines(out)
    ).run()  # (its wait is cut to 0.2 s above)
    assert final.status is RunStatus.STOPPED
    stopped = journal.events[-1]
    assert stopped.kind is EventKind.RUN_STOPPED and "shelf cannot be checked now" in stopped.data.to_json()["reason"]
    assert gateway.sent == [], "nothing was sent with an answer that was never checked"


def test_unattended_wait_for_a_report_ends_when_another_operator_stops_the_run(
    sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    # a console on the ground stops the run while this unattended terminal waits for a report:
    # the wait ends with the run, and the terminal leaves the stop as that operator made it
    executive, journal, gateway = _executive(sysreps, tmp_path, Mode.AUTONOMOUS, "lab_records.xml")
    gateway.stale.add("docks")
    with _unattended_waiting_for_a_report(executive) as (out, finals, running):
        executive.stop("rita", "stopped at the ground console")
    # (joined for 30 s: the terminal's own wait is 120 s, and must end with the run well before)
    assert not running.is_alive(), "the terminal still waits for a report of a stopped run"
    assert [final.status for final in finals] == [RunStatus.STOPPED], out.stream.getvalue()
    stops = [e for e in journal.events if e.kind is EventKind.RUN_STOPPED]
    assert [(e.actor, e.data.to_json()["reason"]) for e in stops] == [("rita", "stopped at the ground console")]
    assert gateway.sent == []


class _YieldingStream(io.StringIO):
    """A stream that gives the CPU away inside every write, as a loaded machine does."""

    def write(self, text: str) -> int:
        written = super().write(text)
        os.sched_yield()
        return written


def test_lines_from_several_threads_stay_whole() -> None:
    # The runner's READY line and the printer's step header come from two threads; a reader
    # that waits for "READY run <id>" must never get the header glued to the id.
    stream = _YieldingStream()
    terminal = TerminalLines(stream)
    said = {f"thread {t} line {n}" for t in range(4) for n in range(200)}

    def say_all(thread: int) -> None:
        for n in range(200):
            terminal.say(f"thread {thread} line {n}")

    threads = [threading.Thread(target=say_all, args=(t,)) for t in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(stream.getvalue().splitlines()) == sorted(said)
