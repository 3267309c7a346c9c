"""The IVA procedure run onboard: the habitat runs it, the ground supervises across 1.3 s each way.

``caretaker run --onboard`` on the ground host uplinks the procedure as a signed unit through the
emulated link to the habitat's onboard executive (a part of its ``caretaker up``), which runs it
next to the robot; the ground follows the run's events and stores them. The run completes, the
arm did every motion once (counted on the habitat), and the ground's audit log is the habitat's
chain event for event, hash for hash.

While it runs, a second signed unit is sent as anyone on the link could (:mod:`unit_sender`): it
is refused, the robot being busy; sent again byte for byte once the first run has ended, within
its lifetime, it is refused again with the first answer and nothing moves.

Then, on the world that run left, a second onboard run loses the filter from the gripper while the
arm pulls it out (:mod:`habitat_slip`): the habitat's own executive watches the procedure's monitor
on the grasp, halts the arm and goes to the contingency step, and the ground's record of it is the
habitat's chain. It comes last: the first test counts every command and motion of the flight.
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
from pride.events import EventKind
from pride.robot_sides import robot_side_for
from procedure_language.lint import check_procedure
from procedure_language.parser import load_procedure
from procedure_language.sysrep import load_sysrep_dir
from records.audit_chain import verify_chain

from .flight_support import (
    DELAY,
    PROCEDURE,
    PULL_OUT,
    RUN_TIMEOUT_S,
    Flight,
    assert_flown_exactly_once,
    commands,
    flight,
    result_of,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=60), pytest.mark.timeout(900)]

SENDER = Path(__file__).with_name("unit_sender.py")
SLIP = Path(__file__).with_name("habitat_slip.py")
#: The clean filter the second run records: the first run put CDRA-F-0012 in the cabinet.
SECOND_CLEAN_FILTER = "CDRA-F-0013"
#: The simulation's pace while the filter is pulled out in the second run: flat out, the 1.3 s pull
#: ends before the habitat's executive has seen the grasp go empty, and there is nothing to halt.
PULL_PACE = 0.25


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


def test_the_filter_slipping_out_mid_pull_onboard_halts_the_arm_goes_to_the_contingency_and_comes_down(
    flown: tuple[Flight, str, str, dict[str, str]],
) -> None:
    """A second onboard run, on the world the first left: the filter it seated is the one taken out.
    It slips out of the gripper while the arm pulls it (the pull paced at :data:`PULL_PACE`, so that
    it is still moving when the violation is seen); the habitat's executive, not the ground 2.6 s
    away, sees the grasp ``empty`` (the monitor of steps ``remove_dirty`` and ``place_dirty``),
    halts the pull and goes to ``filter_slipped``: nothing is carried to the rack, the arm comes to
    rest, and the violation with its value is on both records, hash for hash."""
    f = flown[0]
    steps = {step.id: step for step in load_procedure(PROCEDURE).steps}
    contingency = steps["filter_slipped"]
    slip = f.hosts.python(
        f.hosts.habitat, str(SLIP), PULL_OUT, f"--pace={PULL_PACE}", f"--then={f.time_scale}", ready=r"^READY slip"
    )
    motions_before = f.probe.printed
    run = f.run("--onboard", f"--set=clean_filter_id={SECOND_CLEAN_FILTER}", record=False)
    try:
        slipped = slip.wait_for_line(r"^(NOT )?SLIPPED ", RUN_TIMEOUT_S)
        assert slipped.startswith("SLIPPED "), slipped  # the filter was held, mid-pull, when it slipped
        run_id, status = result_of(run)
        slip.wait_for_line(rf"^PACE {f.time_scale} set", 60)  # the pull over, the simulation as fast as before
    finally:
        slip.stop()

    events = f.events(run_id)
    (pull,) = [
        s.instruction
        for s, _ in commands(events)
        if s.data.to_json()["command"] == "execute_plan" and s.data.to_json()["args"]["trajectory"] == PULL_OUT
    ]
    assert (pull or "").split(".")[0] == str(steps["remove_dirty"].number), pull
    (violated,) = [e for e in events if e.kind is EventKind.MONITOR_VIOLATED]
    said = violated.data.to_json()
    assert (said["value"], said["action"]) == ("empty", "goto:filter_slipped"), said
    assert violated.actor == "PAX" and violated.instruction == pull, violated  # seen during the pull
    (halt,) = [e for e in events if e.kind is EventKind.HALT]
    assert halt.actor == "PAX" and halt.instruction == pull, halt
    assert [e.instruction for e in events if e.kind is EventKind.INSTRUCTION_HALTED] == [pull]
    (went,) = [e for e in events if e.kind is EventKind.WENT_TO]
    assert went.data.to_json()["next"] == contingency.instructions[0].number, went
    after = [e for e in events if e.seq > went.seq]
    assert {(e.instruction or "").split(".")[0] for e in after} <= {str(contingency.number), ""}, after
    assert status == "completed"  # the unit confirmed the contingency's manual: it ends there
    moved = [
        s.data.to_json()["args"]["trajectory"]
        for s, _ in commands(events)
        if s.data.to_json()["command"] == "execute_plan" and s.seq > violated.seq
    ]
    assert not moved, moved  # no motion after the violation: the filter was never carried to the rack

    # The arm as the habitat saw it: the pull-out, stopped short, was the last execution; the arm at rest.
    seen = _printed_since(f, motions_before)
    executed = [line.split()[2:] for line in seen if line.startswith("EXECUTED ")]
    assert executed and executed[-1][0] == PULL_OUT and executed[-1][1] != "SUCCEEDED", executed
    last_motion = max(i for i, line in enumerate(seen) if line.startswith("MOVING "))
    f.probe.wait_for_line(r"^STILL ", 60, after=motions_before + last_motion + 1)
    print(f"onboard slip: {slipped}; the pull-out {' '.join(executed[-1])}; {halt.data.to_json()['reason']}")

    ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
    assert [(e.seq, e.kind, e.hash) for e in ground] == [(e.seq, e.kind, e.hash) for e in habitat]
    (on_habitat,) = [e for e in habitat if e.kind == EventKind.MONITOR_VIOLATED.value]
    assert json.loads(on_habitat.data)["value"] == "empty"
    assert verify_chain(run_id, ground).ok, verify_chain(run_id, ground).describe()


def _printed_since(f: Flight, count: int) -> list[str]:
    """The probe's lines printed after its first ``count`` (it keeps the last 400)."""
    lines = list(f.probe.output)
    first = f.probe.printed - len(lines)
    assert first <= count, f"the probe's lines after {count} were dropped"
    return lines[count - first :]
