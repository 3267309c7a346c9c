"""`caretaker run` as a real process: unattended runs, refusal to start broken procedures, and a
runner killed mid-command then resumed with nothing lost or repeated.

The runner talks to the lab bench gateway (``PRIDE_GATEWAY=support.lab_gateway:open_lab``) because the
robot side is not needed to test the runner; ``LAB_GATEWAY_BLOCK`` makes one command never answer
so the kill lands while it is in flight.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
from collections import Counter
from pathlib import Path

import pytest

from console.accounts import AccountStore
from pride.events import PAX, EventKind
from records.audit_log import AuditLog
from support import lab_gateway
from support.audit import AuditDatabase
from support.procedures import FIXTURES, REPO
from support.processes import COMMAND_HANG_S, ManagedProcess, caretaker

PROCEDURE = str(FIXTURES / "lab_all_kinds.xml")
#: The lab binding has no deployment: hazardous commands need a second operator's approval (bob's).
ANSWERS = ["--set", "target=dock", "--confirm-manual", "--confirm-hazardous", "--approver", "bob"]
BOB_PASSWORD = "bob-battery-staple"


@pytest.fixture
def setup(tmp_path: Path, database: AuditDatabase) -> tuple[dict[str, str], str, list[str]]:
    binding = tmp_path / "lab_binding.yaml"
    binding.write_text("# the lab bench gateway needs no configuration\nrobot: lab\n")
    env = dict(os.environ)
    env["PRIDE_GATEWAY"] = lab_gateway.PRIDE_GATEWAY
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(lab_gateway.IMPORT_ROOT), env.get("PYTHONPATH")]))
    env["LAB_GATEWAY_IMAGES"] = str(tmp_path / "images")
    env["CARETAKER_APPROVER_PASSWORD"] = BOB_PASSWORD
    db = database.url  # SQLite and PostgreSQL in turn (conftest.py)
    accounts = AccountStore(database.owner_url)
    try:
        accounts.add("bob", "operator", BOB_PASSWORD, name="Bob (approver)")
    finally:
        accounts.close()
    common = [
        "--rehearsal",  # the lab procedure is a draft; the lab bench's systems are simulated in the runner
        "--binding",
        str(binding),
        "--db",
        db,
        "--sysrep-dir",
        str(REPO / "sysrep"),
        "--sysrep-dir",
        str(FIXTURES / "sysrep"),
    ]
    return env, db, common


def run(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "run", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        stdin=subprocess.DEVNULL,
    )


def runner_at(env: dict[str, str], common: list[str], line: str) -> ManagedProcess:
    """An unattended ``caretaker run`` of the lab procedure, once it printed ``line``."""
    printed = threading.Event()
    runner = caretaker(
        "run",
        PROCEDURE,
        "--auto",
        "--user",
        "alice",
        *common,
        *ANSWERS,
        env=env,
        on_line=lambda _name, text: printed.set() if text == line else None,
    )
    try:
        runner.wait_ready(60)
        assert printed.wait(60), runner.tail()
    except BaseException:
        runner.stop()
        raise
    return runner


def test_unattended_run_completes_with_answers_logged_as_the_user(setup: tuple[dict[str, str], str, list[str]]) -> None:
    env, db, common = setup
    proc = run(env, PROCEDURE, "--auto", "--user", "alice", *common, *ANSWERS)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Step 2  Inspect" in proc.stdout
    assert "RESULT completed" in proc.stdout
    log = AuditLog(db)
    ((run_id, _, procedure_id),) = log.runs()
    events = log.events(run_id)
    assert procedure_id == "lab_all_kinds"
    assert [e.actor for e in events if e.kind is EventKind.OPERATOR_INPUT] == ["alice"]
    approvals = [(e.kind, e.actor) for e in events if e.kind.value.startswith("approval_")]
    assert approvals == [(EventKind.APPROVAL_REQUESTED, "alice"), (EventKind.APPROVAL_GIVEN, "bob")]
    vent = next(e for e in events if e.kind is EventKind.COMMAND_SENT and e.instruction == "2.1")
    assert (vent.data.to_json()["requested_by"], vent.data.to_json()["approved_by"]) == ("alice", "bob")
    assert events[0].data.to_json()["rehearsal"] is True and events[0].data.to_json()["release"] is None
    assert events[-1].kind is EventKind.RUN_COMPLETED
    assert log.verify(run_id).ok, log.verify(run_id).describe()


def test_a_hazardous_command_without_a_second_operator_stops_an_unattended_run_and_self_approval_is_refused(
    setup: tuple[dict[str, str], str, list[str]],
) -> None:
    env, db, common = setup
    answers = ANSWERS[: ANSWERS.index("--approver")]
    proc = run(env, PROCEDURE, "--auto", "--user", "alice", *common, *answers)
    assert proc.returncode == 1
    assert "waiting for a second operator's approval: give --approver USER" in proc.stdout, proc.stdout
    assert "LAB executing vent" not in proc.stdout
    itself = run(env, PROCEDURE, "--auto", "--user", "bob", *common, *ANSWERS)
    assert itself.returncode == 2 and "a second operator must approve, not bob" in itself.stderr, itself.stderr
    wrong = run({**env, "CARETAKER_APPROVER_PASSWORD": "not-bobs"}, PROCEDURE, "--auto", "--user", "alice", *common)
    assert wrong.returncode == 1  # no --approver: the password is not even read
    guessed = run(
        {**env, "CARETAKER_APPROVER_PASSWORD": "not-bobs"}, PROCEDURE, "--auto", "--user", "alice", *common, *ANSWERS
    )
    assert guessed.returncode == 2 and "bob: unknown user or wrong password" in guessed.stderr, guessed.stderr
    draft = run(env, PROCEDURE, "--auto", "--user", "alice", *common[1:], *ANSWERS)
    assert draft.returncode == 2
    assert "lab_all_kinds.xml is a draft (never released)" in draft.stderr and "(--rehearsal)" in draft.stderr


def test_unattended_run_stops_and_says_which_option_answers_the_record(
    setup: tuple[dict[str, str], str, list[str]],
) -> None:
    env, db, common = setup
    proc = run(env, PROCEDURE, "--auto", "--user", "alice", *common)
    assert proc.returncode == 1
    assert "pass --set target=VALUE" in proc.stdout
    assert "RESULT stopped" in proc.stdout
    assert "LAB executing" not in proc.stdout


def test_a_procedure_with_lint_errors_does_not_start(setup: tuple[dict[str, str], str, list[str]]) -> None:
    env, db, common = setup
    proc = run(env, str(FIXTURES / "broken" / "unknown_command.xml"), "--auto", "--user", "alice", *common)
    assert proc.returncode == 1
    assert "unknown command 'mvoe'" in proc.stderr and "does not start" in proc.stderr
    assert AuditLog(db).runs() == []


def test_killed_runner_resumes_and_learns_the_outcome_of_its_command_in_flight_without_running_it_again(
    setup: tuple[dict[str, str], str, list[str]], tmp_path: Path
) -> None:
    env, db, common = setup
    env = {**env, "LAB_GATEWAY_LEDGER": str(tmp_path / "ledger.json")}  # the habitat's memory of keys
    runner = runner_at({**env, "LAB_GATEWAY_HOLD_REPLY": "capture"}, common, "LAB executed capture, holding its reply")
    try:
        runner.kill()  # SIGKILL while the capture's reply is on its way
    finally:
        runner.stop()
    log = AuditLog(db)
    ((run_id, _, _),) = log.runs()
    before = log.events(run_id)
    assert before[-1].kind is EventKind.COMMAND_SENT and before[-1].instruction == "2.3"
    key = before[-1].data.to_json()["key"]

    # resumed unattended: the capture's key goes again by itself; the habitat answers what it did
    resumed = run(env, "--resume", run_id, "--user", "bob", *common, *ANSWERS[:-2])  # past the vent: no approver
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert "RESULT completed" in resumed.stdout
    # on failure: the keys the resumed runner sent, and every key the habitat's ledger holds
    said = f"{resumed.stdout}\n--- ledger: {(tmp_path / 'ledger.json').read_text()}"
    assert f"sent again Capture Image for dock_view [{key}]" in resumed.stdout, said
    assert "LAB executing capture" not in resumed.stdout, said

    events = log.events(run_id)
    assert [e.seq for e in events] == list(range(1, len(events) + 1))  # nothing lost, nothing twice
    assert [(e.seq, e.kind, e.data) for e in events[: len(before)]] == [(e.seq, e.kind, e.data) for e in before]
    sent = Counter(
        (e.instruction, e.data.to_json()["command"], e.data.to_json()["key"])
        for e in events
        if e.kind is EventKind.COMMAND_SENT
    )
    assert sent[("2.3", "capture", key)] == 2 and len({k for (n, _, k) in sent if n == "2.3"}) == 1
    again = [
        (e.kind, e.actor, e.data.to_json().get("resend", False))
        for e in events
        if e.instruction == "2.3" and e.kind in (EventKind.COMMAND_SENT, EventKind.COMMAND_RESULT)
    ]
    assert again == [
        (EventKind.COMMAND_SENT, PAX, False),
        (EventKind.COMMAND_SENT, PAX, True),
        (EventKind.COMMAND_RESULT, PAX, False),
    ]
    result = next(e for e in events if e.instruction == "2.3" and e.kind is EventKind.COMMAND_RESULT)
    assert result.data.to_json()["outcome"] == "succeeded" and result.data.to_json()["values"]["label"] == "dock_view"
    assert [e.actor for e in events if e.kind is EventKind.RUN_RESUMED] == ["bob"]
    completed = Counter(e.instruction for e in events if e.kind is EventKind.INSTRUCTION_COMPLETED)
    assert all(count == 1 for count in completed.values()), completed
    assert events[-1].kind is EventKind.RUN_COMPLETED
    check = log.verify(run_id)  # the crash and the resumed runner left one unbroken chain
    assert check.ok and check.events == len(events), check.describe()


def test_ctrl_c_halts_the_command_in_flight_and_an_unattended_run_then_stops(
    setup: tuple[dict[str, str], str, list[str]],
) -> None:
    env, db, common = setup
    runner = runner_at({**env, "LAB_GATEWAY_BLOCK": "vent"}, common, "LAB executing vent")
    try:
        runner.proc.send_signal(signal.SIGINT)  # Ctrl-C once
        with contextlib.suppress(subprocess.TimeoutExpired):
            runner.proc.wait(60)
        assert runner.proc.returncode == 1, runner.tail()
    finally:
        runner.stop()
    assert "HALT (Ctrl-C)" in runner.tail()
    log = AuditLog(db)
    ((run_id, _, _),) = log.runs()
    events = log.events(run_id)
    halt = next(e for e in events if e.kind is EventKind.HALT)
    assert (halt.actor, halt.instruction, halt.data.to_json()["reason"], halt.data.to_json()["key"]) == (
        "alice",
        "2.1",
        "Ctrl-C at the terminal",
        f"{run_id}/2.1/1",
    )
    assert halt.data.to_json()["cancel"] == {"stopped": True, "message": "stopped where it was"}
    result = next(e for e in events if e.kind is EventKind.COMMAND_RESULT and e.instruction == "2.1")
    assert (result.data.to_json()["outcome"], result.data.to_json()["success"]) == ("halted", False)
    halted = next(e for e in events if e.kind is EventKind.INSTRUCTION_HALTED)
    assert (halted.actor, halted.instruction, halted.data.to_json()["next"]) == ("alice", "2.1", "2.1")
    assert not any(e.kind is EventKind.INSTRUCTION_COMPLETED and e.instruction == "2.1" for e in events)
    assert events[-1].kind is EventKind.RUN_STOPPED and "halted by alice" in events[-1].data.to_json()["reason"]
    assert log.verify(run_id).ok


def test_a_run_from_a_step_needs_what_the_skipped_steps_bound_and_its_report_says_where_it_started(
    setup: tuple[dict[str, str], str, list[str]],
) -> None:
    env, db, common = setup
    refused = run(env, PROCEDURE, "--auto", "--user", "alice", *common, "--from", "finish")
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "--from finish: the steps it skips would have bound target (read at " in refused.stderr
    assert "give it with --set NAME=VALUE" in refused.stderr
    log = AuditLog(db)
    assert log.runs() == []  # nothing started, nothing recorded
    proc = run(env, PROCEDURE, "--auto", "--user", "alice", *common, *ANSWERS, "--from", "finish", "--to", "4")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "RESULT completed" in proc.stdout and "Step 2  Inspect" not in proc.stdout
    ((run_id, _, _),) = log.runs()
    events = log.events(run_id)
    assert events[0].data.to_json()["section"] == {"from": "finish", "to": "4", "given": {"target": "dock"}}
    assert [e.instruction for e in events if e.kind is EventKind.INSTRUCTION_STARTED][0] == "4.1"
    assert not [e for e in events if e.instruction and e.instruction.startswith("5.")]
    out = Path(env["LAB_GATEWAY_IMAGES"]).parent / "reports"
    subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "report", run_id, "--db", db, "--out", str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=COMMAND_HANG_S,
        check=True,
    )
    report = (out / f"{run_id}.md").read_text(encoding="utf-8")
    assert (
        "Part of the procedure: started at step 4 (Finish), to end after step 4 (Finish); given for the steps "
        "before: target = dock" in report
    ), report
