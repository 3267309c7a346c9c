"""Onboard runs handed to a supervisor through the ground database (``caretaker run --onboard
--via-supervisor``, caretaker/via_supervisor.py) and supervised by ``caretaker supervise``
(caretaker/supervise_command.py), in one process on a SQLite ground database.

The habitat is the lab bench's behind the link emulated in tests/onboard/test_follow_requests.py:
the supervisor's session. A run handed with no supervisor is withdrawn; one handed to a
supervisor runs on its session and the runner shows it from the database to its end; a
supervisor that stops leaves a run holding on the habitat, its handoff ``detached``; one that dies
has its run taken over by another supervisor of the binding. The real
processes across the real link: tests/flight/test_onboard_supervise.py.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from caretaker.supervise_command import Supervisor, serve_all
from caretaker.supervise_command import main as supervise_main
from caretaker.via_supervisor import hand_to_supervisor
from ground.change_feed import ChangeNotice, open_change_feed
from ground.run_hosts import PublishedView, RunHosting
from onboard.habitat_runs import HabitatRuns
from onboard.unit import OperatorAction, Unit
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog
from records.onboard_handoffs import OnboardHandoffs
from support.procedures import REPO
from support.web_server import new_ground_database

from .test_follow_requests import LinkedHabitat
from .test_habitat_runs import PROCEDURE, act, habitat, make_unit, sysreps, uplink

__all__ = ["habitat", "make_unit", "sysreps"]  # the fixtures, used here by name

pytestmark = [pytest.mark.timeout(60), pytest.mark.slow(seconds=80)]


def _runner(
    tmp_path: Path, *, within: float = 10.0, at_consoles: bool = False, db: str | None = None, no_follow: bool = False
) -> argparse.Namespace:
    """``caretaker run``'s options as the runner reads them (``db``: a SQLite file in ``tmp_path`` by default)."""
    db = db or f"sqlite:///{tmp_path / 'ground.db'}"
    return argparse.Namespace(
        db=db, binding="lab.yaml", raw=False, at_consoles=at_consoles, supervisor_within=within, no_follow=no_follow
    )


def test_a_run_no_supervisor_takes_is_withdrawn_and_the_runner_says_so(
    make_unit: Callable[..., Unit], sysreps: dict[str, SysRep], tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    args = _runner(tmp_path, within=0.5)
    audit = AuditLog(args.db)
    try:
        unit = make_unit()
        assert hand_to_supervisor(args, audit, unit, check_procedure(PROCEDURE, sysreps)) == 2
        handoff = OnboardHandoffs(audit.engine).get(unit.run_id)
        assert handoff is not None and handoff.state == "withdrawn"
    finally:
        audit.close()
    said = capfd.readouterr().out
    assert f"no supervisor took run {unit.run_id} within 0.5 s: withdrawn, nothing went up" in said
    assert "caretaker supervise --binding lab.yaml --db sqlite:///" in said


def test_a_handed_run_goes_up_on_the_supervisors_session_and_its_runner_follows_it_from_the_database(
    habitat: tuple[HabitatRuns, list[Any]],
    make_unit: Callable[..., Unit],
    sysreps: dict[str, SysRep],
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
) -> None:
    runs, _ = habitat
    args = _runner(tmp_path)
    audit = AuditLog(args.db)
    link = LinkedHabitat(runs)
    supervisor = Supervisor(link.endpoint, "lab.yaml", audit, sysreps, client=link)
    checked = check_procedure(PROCEDURE, sysreps)
    completed, holding = make_unit(), make_unit(values={})  # the second holds at the record 1.2

    async def fly() -> tuple[int, int]:
        serving = asyncio.create_task(supervisor.serve())
        first = await asyncio.to_thread(hand_to_supervisor, args, audit, completed, checked)
        attended = argparse.Namespace(**{**vars(args), "at_consoles": True})  # the hold waits for a console
        second = asyncio.create_task(asyncio.to_thread(hand_to_supervisor, attended, audit, holding, checked))
        while not any(e["kind"] == "awaiting_operator" for e in runs.events(holding.run_id, 0).events):
            await asyncio.to_thread(runs.events, holding.run_id, 0, 5)  # wait on the habitat for its next event
        supervisor.stop()  # SIGTERM
        assert await serving == 0
        return first, await second

    try:
        first, second = asyncio.run(fly())
        assert first == 0 and second == 1
        here, there = audit.stored_events(completed.run_id), runs.audit.stored_events(completed.run_id)
        assert [(e.seq, e.hash) for e in here] == [(e.seq, e.hash) for e in there] and there[-1].kind == "run_completed"
        handoffs = OnboardHandoffs(audit.engine)
        done, held = handoffs.get(completed.run_id), handoffs.get(holding.run_id)
        assert done is not None and (done.state, done.result, done.supervisor) == (
            "ended",
            "completed",
            supervisor.name,
        )
        assert held is not None and held.state == "detached"
        assert runs.status().active_run == holding.run_id  # it goes on on the habitat, holding for an operator
    finally:
        audit.close()
    said = capfd.readouterr().out
    assert f"READY run {completed.run_id}" in said and f"RESULT completed run {completed.run_id}" in said
    assert f"RESULT detached run {holding.run_id}" in said
    assert f"follow it again: caretaker run --attach {holding.run_id} --binding lab.yaml" in said
    assert len([c for c in link.crossings if c.service == "/caretaker_onboard/uplink"]) == 2  # one session, two units


def test_a_runner_that_does_not_follow_ends_once_the_habitat_took_the_unit_and_the_supervisor_hosts_the_run(
    habitat: tuple[HabitatRuns, list[Any]],
    make_unit: Callable[..., Unit],
    sysreps: dict[str, SysRep],
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
) -> None:
    """``--no-follow``: the runner leaves the run to its supervisor, which hosts it for the consoles."""
    runs, _ = habitat
    args = _runner(tmp_path, at_consoles=True, no_follow=True)
    audit = AuditLog(args.db)
    link = LinkedHabitat(runs)
    supervisor = Supervisor(link.endpoint, "lab.yaml", audit, sysreps, client=link)
    holding = make_unit(values={})  # holds at the record 1.2 for a console: it is not over when the runner ends
    hosting = RunHosting(audit.engine, host="a console")

    async def fly() -> int:
        serving = asyncio.create_task(supervisor.serve())
        code = await asyncio.to_thread(hand_to_supervisor, args, audit, holding, check_procedure(PROCEDURE, sysreps))
        record = hosting.record(holding.run_id)
        assert record is not None and record.alive and record.host == supervisor.name  # hosted for the consoles
        supervisor.stop()
        assert await serving == 0
        return code

    try:
        assert asyncio.run(fly()) == 0
        assert runs.status().active_run == holding.run_id
    finally:
        hosting.close()
        audit.close()
    said = capfd.readouterr().out
    assert f"READY run {holding.run_id}" in said and "RESULT" not in said
    assert f"followed no further: {supervisor.name} keeps its record and hosts it for the consoles" in said


def test_a_supervisor_whose_lease_runs_out_is_gone_and_its_runner_says_the_run_goes_on(
    make_unit: Callable[..., Unit], sysreps: dict[str, SysRep], tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """A supervisor killed while it follows a run: nothing says ``detached`` but its lease running out."""
    args = _runner(tmp_path)
    audit = AuditLog(args.db)
    unit = make_unit()
    handoffs = OnboardHandoffs(audit.engine)
    dying = RunHosting(audit.engine, host="supervisor elsewhere", lease=3.0)

    def supervisor_that_dies(notice: ChangeNotice) -> None:  # takes the run, claims it, then renews nothing
        if notice.payload == f"handed {unit.run_id}" and handoffs.take(unit.run_id, dying.host):
            view = PublishedView({}, "active", "autonomous")
            dying.claim(unit.run_id, binding="lab.yaml", started_by="alice", procedure_view={}, source=lambda: view)
            handoffs.uplinked(unit.run_id)
            dying.close()

    feed = open_change_feed(audit.engine)
    feed.subscribe(supervisor_that_dies)
    try:
        assert feed.connected.wait(10)
        assert hand_to_supervisor(args, audit, unit, check_procedure(PROCEDURE, sysreps)) == 1
        handoff = handoffs.get(unit.run_id)
        assert (
            handoff is not None and handoff.state == "detached" and "lease on the run ran out" in str(handoff.message)
        )
    finally:
        feed.close()
        audit.close()
    said = capfd.readouterr().out
    assert "its supervisor, supervisor elsewhere, no longer follows it: its lease on the run ran out at" in said
    assert f"RESULT detached run {unit.run_id}" in said


@pytest.mark.timeout(180)  # a lease to run out, and the run's records across the emulated link
@pytest.mark.parametrize("kind", ["sqlite", "postgresql"])
def test_a_run_whose_supervisor_died_is_taken_over_by_another_and_its_ground_chain_ends_equal_to_the_habitats(
    habitat: tuple[HabitatRuns, list[Any]],
    make_unit: Callable[..., Unit],
    sysreps: dict[str, SysRep],
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
    request: pytest.FixtureRequest,
    kind: str,
) -> None:
    """Supervisor A takes a handed run, uplinks it and dies (its lease is never renewed) while the
    run holds on the habitat; supervisor B of the same binding takes it over, catches the ground's
    record up and follows it to its end once an operator answers the hold on the habitat. On a
    SQLite file, and on PostgreSQL as supervisors on several hosts share one."""
    runs, _ = habitat
    postgres = request.getfixturevalue("postgres") if kind == "postgresql" else None
    args = _runner(tmp_path, db=new_ground_database(kind, tmp_path, postgres).url)
    audit = AuditLog(args.db)
    unit = make_unit(values={})  # it holds at the record 1.2 until the operator enters it
    handoffs = OnboardHandoffs(audit.engine)
    dying = RunHosting(audit.engine, host="supervisor A", lease=3.0)

    def supervisor_a(notice: ChangeNotice) -> None:  # takes the run, uplinks it, holds it, then renews nothing
        if notice.payload == f"handed {unit.run_id}" and handoffs.take(unit.run_id, dying.host):
            view = PublishedView({}, "active", "autonomous")
            dying.claim(unit.run_id, binding="lab.yaml", started_by="alice", procedure_view={}, source=lambda: view)
            assert uplink(runs, unit).state == "ACCEPTED"
            handoffs.uplinked(unit.run_id)
            dying.close()

    feed = open_change_feed(audit.engine)
    feed.subscribe(supervisor_a)
    supervisor_b = Supervisor(
        LinkedHabitat(runs).endpoint, "lab.yaml", audit, sysreps, client=LinkedHabitat(runs), lease=3.0
    )

    async def fly() -> int:
        runner = asyncio.create_task(
            asyncio.to_thread(hand_to_supervisor, args, audit, unit, check_procedure(PROCEDURE, sysreps))
        )
        while (h := handoffs.get(unit.run_id)) is None or h.state != "uplinked":  # A has it: B starts
            await asyncio.to_thread(runs.events, unit.run_id, 0, 1)
        serving = asyncio.create_task(supervisor_b.serve())
        deadline = time.monotonic() + 60  # A's lease is 3 s: B takes over soon after, or never
        while (h := handoffs.get(unit.run_id)) is not None and h.supervisor != supervisor_b.name:
            assert time.monotonic() < deadline, f"nobody took over the run: {h}"
            await asyncio.sleep(0.1)  # the handoff row has no event of its own to await here
        entered = OperatorAction(
            "key-1", unit.run_id, "enter", "bob", time.time() + 60, {"value": "dock", "instruction": "1.2"}
        )
        assert (await asyncio.to_thread(act, runs, entered)).state == "DONE"
        while (h := handoffs.get(unit.run_id)) is not None and h.state != "ended":
            await asyncio.to_thread(runs.events, unit.run_id, 0, 1)
        supervisor_b.stop()
        assert await serving == 0
        return await runner

    try:
        assert feed.connected.wait(10)
        asyncio.run(fly())
        ended = handoffs.get(unit.run_id)
        assert ended is not None and (ended.state, ended.result, ended.supervisor) == (
            "ended",
            "completed",
            supervisor_b.name,
        )
        here, there = audit.stored_events(unit.run_id), runs.audit.stored_events(unit.run_id)
        assert [(e.seq, e.hash) for e in here] == [(e.seq, e.hash) for e in there] and there[-1].kind == "run_completed"
    finally:
        feed.close()
        audit.close()
    said = capfd.readouterr().out
    assert f"{unit.run_id}: TAKEN OVER from supervisor A (" in said
    assert f"{unit.run_id}: ENDED completed" in said


def test_one_process_supervises_several_bindings_each_taking_only_its_own_runs_and_sigterm_stops_them_all(
    habitat: tuple[HabitatRuns, list[Any]], make_unit: Callable[..., Unit], sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    runs, _ = habitat
    args = _runner(tmp_path)
    audit = AuditLog(args.db)
    lab = Supervisor(LinkedHabitat(runs).endpoint, "lab.yaml", audit, sysreps, client=LinkedHabitat(runs))
    other = Supervisor(LinkedHabitat(runs).endpoint, "other.yaml", audit, sysreps, client=LinkedHabitat(runs))
    unit = make_unit()

    async def fly() -> tuple[int, int]:
        serving = asyncio.create_task(serve_all([lab, other]))
        handed = await asyncio.to_thread(hand_to_supervisor, args, audit, unit, check_procedure(PROCEDURE, sysreps))
        os.kill(os.getpid(), signal.SIGTERM)  # as `kill PID` stops the process: both supervisors
        return handed, await serving

    try:
        assert asyncio.run(fly()) == (0, 0)
        handoff = OnboardHandoffs(audit.engine).get(unit.run_id)
        assert handoff is not None and (handoff.state, handoff.result) == ("ended", "completed")
    finally:
        audit.close()


def test_supervise_refuses_two_bindings_of_one_name_and_a_binding_without_the_links_secret(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    twice = supervise_main(
        ["--binding", str(tmp_path / "a" / "lab.yaml"), "--binding", str(tmp_path / "b" / "lab.yaml")]
    )
    assert twice == 2 and "two --binding files of one name" in capsys.readouterr().err
    local = REPO / "sysrep" / "bindings" / "iva.yaml"  # the simulator's own: no link, no secret
    assert supervise_main(["--binding", str(local), "--db", f"sqlite:///{tmp_path / 'g.db'}"]) == 2
    assert f"{local} has no security.secret_file: units are signed with it" in capsys.readouterr().err
