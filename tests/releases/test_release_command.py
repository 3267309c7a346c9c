"""Releases from the command line: ``caretaker release`` by an author and a second operator, then
``caretaker run`` of the released file, without ``--rehearsal``, on a robot side whose deployment
is not a simulator.

The robot side is the lightest real one: the deployment's own rosbridge server (``caretaker
bridge`` as ``caretaker up`` starts it), reached by the runner's JVM and PAX plugins over a real
socket; the procedure needs no robot part behind it (its one instruction is manual, confirmed
unattended). What this checks is the ground's rule, which the deployment file decides: it has no
``simulator: true``, so only a released version runs there, and a rehearsal does not.
Every ``caretaker`` here is a process of its own, on a SQLite ground database in a file.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import select

from caretaker.processes import REPO
from console.accounts import AccountStore
from pride.events import EventKind
from records.audit_log import AuditLog
from records.releases import procedure_releases
from support.stack import robot_parts, write_deployment

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=20)]

PROCEDURE = """<?xml version="1.0" encoding="UTF-8"?>
<procedure id="bench_walkround" title="Walk round the bench" version="1">
  <uses system="affordance_templates"/>
  <step id="look" title="Look">
    <manual>Check that nothing lies in the arm's reach.</manual>
  </step>
</procedure>
"""
PASSWORDS = {"alice": "alice-secret-1", "bob": "bob-secret-12"}


def _binding(folder: Path) -> Path:
    """A binding of the AT SysRep to the bench robot (the deployment's port; the run gives the one its bridge took)."""
    path = folder / "bench-binding.yaml"
    path.write_text(
        "robot: bench\nrosbridge: ws://127.0.0.1:9090\nsystems:\n"
        f"- sysrep: {REPO / 'sysrep' / 'affordance_templates.yaml'}\n"
        "  plugins: [at_commands, at_telemetry]\n  namespace: /affordance_template_server\n"
    )
    return path


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory, ros_env: dict[str, str]) -> Iterator[tuple[Path, Path, str]]:
    """(binding, deployment, rosbridge URL): a robot side described without ``simulator: true``."""
    folder = tmp_path_factory.mktemp("bench")
    binding = _binding(folder)
    deployment = write_deployment(folder, "iva", name="bench", simulator=None, demo=None, bindings=[str(binding)])
    assert "simulator" not in deployment.read_text()
    with robot_parts(deployment, ros_env, parts=("bridge",)) as parts:
        yield binding, deployment, parts.bridge_url


def _caretaker(*args: str, stdin: str = "", env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``caretaker ARGS`` to its end (a launcher's process, with no gateway stood in by a test)."""
    environment = {k: v for k, v in os.environ.items() if not k.startswith(("PRIDE_GATEWAY", "CARETAKER_"))}
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", *args],
        input=stdin,
        capture_output=True,
        text=True,
        env={**environment, **(env or {})},
        timeout=240,  # a few s of CPU each (the run starts a JVM), beside a busy suite on two cores
    )


def test_a_released_version_runs_on_a_robot_and_its_author_cannot_approve_it(
    tmp_path: Path, bench: tuple[Path, Path, str]
) -> None:
    binding, deployment, url = bench
    db = f"sqlite:///{tmp_path / 'ground.db'}"
    accounts = AccountStore(db)
    for user, password in PASSWORDS.items():
        accounts.add(user, "operator", password)
    accounts.close()
    procedure = tmp_path / "bench_walkround.xml"
    procedure.write_text(PROCEDURE)
    run: tuple[str, ...] = (
        "run",
        str(procedure),
        "--binding",
        str(binding),
        "--deployment",
        str(deployment),
        "--rosbridge",
        url,
    )
    run += ("--auto", "--confirm-manual", "--user", "alice", "--db", db)

    draft = _caretaker(*run)
    assert draft.returncode == 2, draft.stderr
    assert "is a draft (never released)" in draft.stderr
    rehearsal = _caretaker(*run, "--rehearsal")
    assert rehearsal.returncode == 2, rehearsal.stderr
    assert f"a rehearsal runs only against a simulator, and {deployment} is not one" in rehearsal.stderr

    # the author approving their own change: refused, and nothing is written
    own = _caretaker(
        "release", str(procedure), "--user", "alice", "--approver", "alice", "--db", db, stdin="alice-secret-1\n" * 2
    )
    assert own.returncode == 2, own.stderr
    assert "alice asked for its release: a second operator must review and release this version" in own.stderr
    wrong = _caretaker(
        "release", str(procedure), "--user", "alice", "--approver", "bob", "--db", db, stdin="alice-secret-1\nguess\n"
    )
    assert wrong.returncode == 2 and "bob: unknown user or wrong password" in wrong.stderr, wrong.stderr
    audit = AuditLog(db)
    with audit.engine.connect() as connection:
        assert connection.execute(select(procedure_releases)).all() == []

    released = _caretaker(
        "release",
        str(procedure),
        "--user",
        "alice",
        "--approver",
        "bob",
        "--db",
        db,
        env={"CARETAKER_PASSWORD": PASSWORDS["alice"], "CARETAKER_APPROVER_PASSWORD": PASSWORDS["bob"]},
    )
    assert released.returncode == 0, released.stderr
    assert "bench_walkround release 1" in released.stdout and "asked by alice, released by bob" in released.stdout
    with audit.engine.connect() as connection:  # the Author page's rows: a request, then the release with its text
        rows = connection.execute(select(procedure_releases).order_by(procedure_releases.c.id)).all()
    assert [(r.kind, r.user_id, r.release) for r in rows] == [("requested", "alice", None), ("released", "bob", 1)]
    assert rows[1].content == PROCEDURE
    sha = rows[1].sha256

    listed = _caretaker("releases", "list", "--db", db)
    assert listed.returncode == 0, listed.stderr
    assert listed.stdout.splitlines()[1].split("\t")[:5] == ["bench_walkround", "1", sha, "alice", "bob"]

    ran = _caretaker(*run)
    assert ran.returncode == 0, ran.stdout + ran.stderr
    result = next(line for line in ran.stdout.splitlines() if line.startswith("RESULT "))
    assert result.startswith("RESULT completed"), ran.stdout
    started = audit.events(result.split()[3])[0]
    assert started.kind is EventKind.RUN_STARTED
    recorded = started.to_dict()["data"]  # as the log stores it
    assert (recorded["sha256"], recorded["release"], recorded["rehearsal"]) == (sha, 1, False)

    procedure.write_text(PROCEDURE.replace("lies in", "is in"))  # edited after its release
    edited = _caretaker(*run)
    assert edited.returncode == 2, edited.stderr
    assert f"{procedure} changed since release 1 (sha256 {sha[:8]}…" in edited.stderr
    audit.close()
