"""A target whose markers do not support a pose holds the EVA inspection with the reason, and
nothing is registered there.

The shipped EVA inspection, run as an operator runs it (``caretaker run`` with its JVM PAX
plugins, unattended) against the whole EVA robot side, with hull_a's first marker covered or
printed with another id on the simulated panel. The procedure locates hull_a before it registers
the inspection template there; perception refuses, so the locate fails, the run holds for an
operator (and, unattended, stops with that reason), and no ``set_display_object_pose`` is sent
for hull_a after it: a guess is never registered (the template stays where the drawings put it
for the approach). The refusals of perception alone, and a residual over
the tolerance, are test_locate.py's.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from perception_client import PerceptionClient

from caretaker.stack import Stack
from pride.events import EventKind
from records.audit_log import AuditLog
from support.procedures import REPO
from support.stack import robot_parts

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=45)]

#: hull_a's markers (sim/scenes/eva.yaml): the test changes the first.
FIRST, SECOND = 30, 31


@pytest.fixture(scope="module")
def stack(ros_env: dict[str, str]) -> Iterator[Stack]:
    """The shipped EVA robot side, every part (undisplaced: the refusal is the markers', not the world's)."""
    with robot_parts("eva", ros_env) as parts:
        yield parts


@pytest.mark.parametrize(
    ("printed", "said"),
    [
        (-1, f"only marker(s) {SECOND} of {FIRST}, {SECOND} are seen"),
        (99, f"only marker(s) {SECOND} of {FIRST}, {SECOND} are seen; other markers in view: 99"),
    ],
    ids=["covered", "wrong id"],
)
def test_a_refused_locate_holds_the_run_with_its_reason_and_registers_nothing(
    printed: int, said: str, stack: Stack, client: PerceptionClient, ros_env: dict[str, str], tmp_path: Path
) -> None:
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    client.print_marker(FIRST, printed)
    try:
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "caretaker.cli",
                "run",
                str(REPO / "procedures" / "eva_inspection.xml"),
                "--binding",
                str(REPO / "sysrep" / "bindings" / "eva.yaml"),
                "--rosbridge",
                stack.bridge_url,
                "--auto",
                "--user",
                "tester",
                "--db",
                db,
                "--set",
                "damage=false",
                "--confirm-manual",
                "--rehearsal",
            ],
            env=ros_env,
            capture_output=True,
            text=True,
            timeout=600,
            stdin=subprocess.DEVNULL,
        )
    finally:
        client.print_marker(FIRST, FIRST)
    log = AuditLog(db)
    try:
        ((run_id, _, _),) = log.runs()
        events = log.events(run_id)
    finally:
        log.close()
    output = run.stdout[-3000:] + run.stderr[-2000:]
    assert events[-1].kind is EventKind.RUN_STOPPED, output
    results = [e for e in events if e.kind is EventKind.COMMAND_RESULT]
    locate = next(
        e
        for e in results
        if e.data.to_json()["command"] == "locate" and e.data.to_json()["args"]["object"] == "target/hull_a"
    )
    assert locate.data.to_json()["success"] is False and said in locate.data.to_json()["message"], locate.data
    assert said in events[-1].data.to_json()["reason"], events[-1].data  # the hold's reason, in the record of the stop
    # the template was put on hull_a as drawn before the approach; nothing moved it there after
    registered = [
        e.data.to_json()["args"]
        for e in events
        if e.seq > locate.seq
        and e.kind is EventKind.COMMAND_SENT
        and e.data.to_json()["command"] == "set_display_object_pose"
        and e.data.to_json()["args"]["frame"] == "target/hull_a"
    ]
    assert registered == [], f"registered at hull_a after a refused locate: {registered}"
    assert run.returncode != 0, output
