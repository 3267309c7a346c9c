"""The IVA procedure run onboard: the habitat runs it, the ground supervises across 1.3 s each way.

``caretaker run --onboard`` on the ground host uplinks the procedure as a signed unit through the
emulated link to the habitat's onboard executive (a part of its ``caretaker up``), which runs it
next to the robot; the ground follows the run's events and stores them. The run completes, the
arm did every motion once (counted on the habitat), and the ground's audit log is the habitat's
chain event for event, hash for hash.

While it runs, a second signed unit is sent as anyone on the link could (:mod:`unit_sender`): it
is refused, the robot being busy; sent again byte for byte once the first run has ended, within
its lifetime, it is refused again with the first answer and nothing moves.
"""

from __future__ import annotations

import json
import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from onboard.downlink import build_unit
from onboard.unit import sign
from pride.robot_sides import robot_side_for
from procedure_language.lint import check_procedure
from procedure_language.sysrep import load_sysrep_dir
from records.audit_chain import verify_chain

from .flight_support import DELAY, PROCEDURE, Flight, assert_flown_exactly_once, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=60), pytest.mark.timeout(900)]

SENDER = Path(__file__).with_name("unit_sender.py")


@pytest.fixture(scope="module")
def flown(ros_env: dict[str, str]) -> Iterator[tuple[Flight, str, str, dict[str, str]]]:
    """The flight (time scale 0: the motions as fast as the simulation goes; bench/link.py times
    them at 1), its run's id and status, and the second unit's two answers and the habitat's status."""
    with flight(ros_env, delay=DELAY, time_scale="0", onboard=True) as f:
        sender = f.hosts.python(f.hosts.ground, str(SENDER), str(f.binding), str(_second_unit(f)), timeout=180)
        run = f.run("--onboard")
        run.wait_for_line(r"^uplinked unit [0-9a-f]{64}", 120)
        os.kill(sender.proc.pid, signal.SIGUSR1)  # the first run was accepted: the robot is busy
        first = sender.wait_for_line(r"^ANSWER ", 180)
        run_id, status = result_of(run)
        answered = sender.printed
        os.kill(sender.proc.pid, signal.SIGUSR1)  # the first run ended: the robot is idle
        second = sender.wait_for_line(r"^ANSWER ", 180, after=answered)
        os.kill(sender.proc.pid, signal.SIGUSR2)
        habitat_status = sender.wait_for_line(r"^STATUS ", 180)
        yield f, run_id, status, {"first": first, "second": second, "status": habitat_status}


def _second_unit(f: Flight) -> Path:
    """A unit of the same procedure, signed with the link's secret, with a lifetime of 15 minutes."""
    sysreps = load_sysrep_dir(PROCEDURE.parents[1] / "sysrep")
    unit = build_unit(
        check_procedure(PROCEDURE, sysreps),
        run_id=f"replayed-{time.time_ns()}",
        binding=f.binding.name,
        user="mallory",
        mode="autonomous",
        values={"clean_filter_id": "CDRA-F-0012"},
        confirm_manual=True,
        confirm_hazardous=True,
        breakpoints=(),
        lifetime_s=900,
        now=time.time(),
        policy=robot_side_for(f.binding).approvals,
        approver="mallory-2",
    )
    text = unit.to_json()
    secret = f.credentials["rosbridge.secret"].read_text(encoding="utf-8").strip()
    path = f.hosts.folder / "second-unit.json"
    path.write_text(json.dumps({"unit_json": text, "signature": sign(text, secret)}), encoding="utf-8")
    return path


def test_the_iva_procedure_flown_onboard_completes_and_the_ground_keeps_the_habitats_chain(
    flown: tuple[Flight, str, str, dict[str, str]],
) -> None:
    f, run_id, status, _ = flown
    assert_flown_exactly_once(f, run_id, status)
    ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
    assert [(e.seq, e.kind, e.hash) for e in ground] == [(e.seq, e.kind, e.hash) for e in habitat]
    assert verify_chain(run_id, ground).ok, verify_chain(run_id, ground).describe()
    started, ended = ground[0].time, ground[-1].time
    print(f"onboard run {run_id}: {(ended - started).total_seconds():.1f} s on the habitat")


def test_a_unit_refused_while_a_run_was_active_and_replayed_after_it_ended_stays_refused(
    flown: tuple[Flight, str, str, dict[str, str]],
) -> None:
    f, run_id, _, said = flown
    first = json.loads(said["first"].removeprefix("ANSWER "))
    second = json.loads(said["second"].removeprefix("ANSWER "))
    assert first["state"] == "REFUSED" and f"onboard run {run_id} is active" in first["message"], first
    assert second == first  # the first answer, not a run started on an idle robot
    assert f.habitat.onboard_chain(first["run_id"]) == []
    assert len(f.goals()) == len({goal for goal, _ in f.goals()})  # no goal but the first run's (counted there)
    status = json.loads(said["status"].removeprefix("STATUS "))
    assert status["active_run"] == "" and status["units_refused"] == 2 and status["units_answered"] == 2, status
    # the habitat's log shows both refusals, though its parts are not echoed (no --verbose)
    up = f.habitat.up.output
    shown = [line for line in up if line.split()[1:2] == ["SECURITY"] and first["unit_hash"][:12] in line]
    assert len(shown) == 2 and "sent again, refused as before" in shown[1], shown
