"""`caretaker run` as a real process: unattended runs, refusal to start broken procedures, and a
runner killed mid-command then resumed with nothing lost or repeated.

The runner talks to the lab bench gateway (``PRIDE_GATEWAY=lab_gateway:open_lab``) because the
robot side is not needed to test the runner; ``LAB_GATEWAY_BLOCK`` makes one command never answer
so the kill lands while it is in flight.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from collections import Counter
from pathlib import Path

import pytest

from conftest import FIXTURES, HERE, REPO
from pride.audit_log import AuditLog
from pride.events import PAX, EventKind
from support.processes import caretaker

PROCEDURE = str(FIXTURES / "lab_all_kinds.xml")
ANSWERS = ["--set", "target=dock", "--confirm-manual", "--confirm-hazardous"]


@pytest.fixture
def setup(tmp_path: Path, database):
    binding = tmp_path / "lab_binding.yaml"
    binding.write_text("# the lab bench gateway needs no configuration\nrobot: lab\n")
    env = dict(os.environ)
    env["PRIDE_GATEWAY"] = "lab_gateway:open_lab"
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(HERE), env.get("PYTHONPATH")]))
    env["LAB_GATEWAY_IMAGES"] = str(tmp_path / "images")
    db = database.url  # SQLite and PostgreSQL in turn (conftest.py)
    common = ["--binding", str(binding), "--db", db, "--sysrep-dir", str(REPO / "sysrep"),
              "--sysrep-dir", str(FIXTURES / "sysrep")]
    return env, db, common


def run(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "caretaker.cli", "run", *args], env=env, capture_output=True,
                          text=True, timeout=120, stdin=subprocess.DEVNULL)


def test_unattended_run_completes_with_answers_logged_as_the_user(setup) -> None:
    env, db, common = setup
    proc = run(env, PROCEDURE, "--auto", "--user", "alice", *common, *ANSWERS)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Step 2  Inspect" in proc.stdout
    assert "RESULT completed" in proc.stdout
    log = AuditLog(db)
    (run_id, _, procedure_id), = log.runs()
    events = log.events(run_id)
    assert procedure_id == "lab_all_kinds"
    assert [e.actor for e in events if e.kind is EventKind.OPERATOR_INPUT] == ["alice"]
    assert [e.actor for e in events if e.kind is EventKind.CONFIRMATION] == ["alice"]
    assert events[-1].kind is EventKind.RUN_COMPLETED
    assert log.verify(run_id).ok, log.verify(run_id).describe()


def test_unattended_run_stops_and_says_which_option_answers_the_record(setup) -> None:
    env, db, common = setup
    proc = run(env, PROCEDURE, "--auto", "--user", "alice", *common)
    assert proc.returncode == 1
    assert "pass --set target=VALUE" in proc.stdout
    assert "RESULT stopped" in proc.stdout
    assert "LAB executing" not in proc.stdout


def test_a_procedure_with_lint_errors_does_not_start(setup) -> None:
    env, db, common = setup
    proc = run(env, str(FIXTURES / "broken" / "unknown_command.xml"), "--auto", "--user", "alice", *common)
    assert proc.returncode == 1
    assert "unknown command 'mvoe'" in proc.stderr and "does not start" in proc.stderr
    assert AuditLog(db).runs() == []


def test_killed_runner_resumes_without_losing_or_repeating_actions(setup) -> None:
    env, db, common = setup
    in_flight = threading.Event()

    def watch(_name: str, line: str) -> None:
        if line == "LAB executing capture":
            in_flight.set()

    runner = caretaker("run", PROCEDURE, "--auto", "--user", "alice", *common, *ANSWERS,
                       env={**env, "LAB_GATEWAY_BLOCK": "capture"}, on_line=watch)
    try:
        runner.wait_ready(60)
        assert in_flight.wait(60), runner.tail()
        runner.kill()  # SIGKILL while the capture command is in flight
    finally:
        runner.stop()
    log = AuditLog(db)
    (run_id, _, _), = log.runs()
    before = log.events(run_id)
    assert before[-1].kind is EventKind.COMMAND_SENT and before[-1].instruction == "2.3"

    # resuming unattended without a decision must not resend the in-flight command
    undecided = run(env, "--resume", run_id, "--user", "bob", *common, *ANSWERS)
    assert undecided.returncode == 1, undecided.stdout + undecided.stderr
    assert "pass --in-flight resend or --in-flight skip" in undecided.stdout
    assert "LAB executing" not in undecided.stdout

    resumed = run(env, "--resume", run_id, "--user", "bob", "--in-flight", "resend", *common, *ANSWERS)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert "RESULT completed" in resumed.stdout

    events = log.events(run_id)
    assert [e.seq for e in events] == list(range(1, len(events) + 1))  # nothing lost, nothing twice
    assert [(e.seq, e.kind, e.data) for e in events[: len(before)]] == [(e.seq, e.kind, e.data) for e in before]
    sent = Counter((e.instruction, e.data["command"]) for e in events if e.kind is EventKind.COMMAND_SENT)
    assert sent == {("1.3", "move"): 1, ("2.1", "vent"): 1, ("2.3", "capture"): 2, ("4.1/1.1", "count"): 1,
                    ("5.1", "move"): 1}
    resend = [e for e in events if e.instruction == "2.3" and e.kind in (EventKind.RETRY, EventKind.COMMAND_SENT)]
    assert [(e.kind, e.actor) for e in resend] == [(EventKind.COMMAND_SENT, PAX), (EventKind.RETRY, "bob"),
                                                  (EventKind.COMMAND_SENT, "bob")]
    assert [e.actor for e in events if e.kind is EventKind.RUN_RESUMED] == ["bob", "bob"]
    completed = Counter(e.instruction for e in events if e.kind is EventKind.INSTRUCTION_COMPLETED)
    assert all(count == 1 for count in completed.values()), completed
    assert events[-1].kind is EventKind.RUN_COMPLETED
    check = log.verify(run_id)  # the crash and the resumed runner left one unbroken chain
    assert check.ok and check.events == len(events), check.describe()
