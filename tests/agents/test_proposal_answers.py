"""What becomes of an agent's proposal on the ground: a console's answers (console/proposals.py) and
the runner that takes an accepted one (``caretaker run --proposal``, records/proposal_runs.py).

A real ground database (SQLite) with the shipped procedures, the IVA filter change released by two
operators; the proposals are made as an agent's desk stores them. Accepting one through to a run
on the real robot, in Chromium: tests/web/test_web_on_real_stack.py.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import update

from console.accounts import AccountStore
from console.actions import ActionRefused
from console.catalog import Catalog
from console.proposals import ProposalDesk
from onboard.unit import Unit, UnitError
from pride.accepted_proposal import AcceptedProposal
from pride.robot_sides import robot_side_for
from pride.run_setup import RunSetup, load_sysreps
from procedure_language.lint import check_procedure
from records.agent_proposals import CitedTelemetry, NewProposal, ProposalStore
from records.agent_tables import agent_proposals
from records.audit_log import AuditLog
from records.proposal_runs import ProposalNotRunnable, proposal_taken
from records.releases import ReleaseStore, procedure_digest, version_for_run
from records.robot_control import RobotControl
from support.procedures import REPO

IVA = "iva_cdra_filter_replacement.xml"
SYSREPS = load_sysreps([REPO / "sysrep"])


@dataclass
class Ground:
    log: AuditLog
    catalog: Catalog
    store: ProposalStore
    sha256: str

    def propose(self, **changes: Any) -> int:
        """A proposal of the released IVA procedure on the IVA robot, as a desk stores one."""
        fields: dict[str, Any] = {
            "agent": "daphne",
            "procedure": "iva_cdra_filter_replacement",
            "procedure_file": IVA,
            "sha256": self.sha256,
            "release": 1,
            "robot": "iva",
            "binding": "iva.yaml",
            "inputs": {},
            "reason": "cabin CO2 above its yellow limit",
            "cited": (CitedTelemetry("cdra", "co2_partial_pressure", 4.4, "yellow"),),
        }
        return self.store.propose(NewProposal(**(fields | changes))).id

    def setup(self) -> RunSetup:
        """The set-up ``caretaker run`` makes of the IVA procedure on the IVA binding."""
        side = robot_side_for(REPO / "sysrep" / "bindings" / "iva.yaml")
        store = ReleaseStore(self.log.engine)
        return RunSetup.prepare(
            self.catalog.procedure_path(IVA),
            side,
            SYSREPS,
            version=lambda checked, side: version_for_run(store, checked, IVA, side, rehearsal=False),
        )


@pytest.fixture
def ground(tmp_path: Path) -> Iterator[Ground]:
    procedures = tmp_path / "procedures"
    shutil.copytree(REPO / "procedures", procedures)
    log = AuditLog(f"sqlite:///{tmp_path / 'ground.db'}")
    checked = check_procedure(procedures / IVA, SYSREPS)
    sha = procedure_digest(checked)
    ReleaseStore(log.engine).release_by_two(
        checked.procedure.id, sha, "alice", "bob", f"procedures/{IVA}", (procedures / IVA).read_text()
    )
    catalog = Catalog(procedures, REPO / "sysrep" / "bindings", (REPO / "sysrep",))
    yield Ground(log, catalog, ProposalStore(log.engine), sha)
    log.close()


@pytest.fixture
def desk(ground: Ground) -> Iterator[ProposalDesk]:
    from console.run_board import RunBoard

    accounts = AccountStore(ground.log.url)
    board = RunBoard(ground.catalog, ground.log, accounts=accounts, console="console A")
    desk = ProposalDesk(board)
    yield desk
    desk.close()
    board.close()
    accounts.close()


def refusal(call: Any) -> ActionRefused:
    with pytest.raises(ActionRefused) as refused:
        call()
    return refused.value


def test_a_decline_needs_a_reason_and_reaches_the_agent_and_an_answered_proposal_takes_no_more_answers(
    ground: Ground, desk: ProposalDesk
) -> None:
    proposal = ground.propose()
    assert refusal(lambda: desk.decline("alice", proposal, "  ")).status == 400
    assert ground.store.get(proposal).state == "open"  # type: ignore[union-attr]
    desk.decline("alice", proposal, "one swap at a time")
    declined = ground.store.get(proposal)
    assert declined is not None
    assert (declined.state, declined.closed_by, declined.answer) == ("declined", "alice", "one swap at a time")
    again = refusal(lambda: desk.accept("bob", proposal, "manual", onboard=False))
    assert (again.status, again.message) == (409, f"proposal {proposal} is declined: nothing to answer")
    assert refusal(lambda: desk.decline("bob", 999, "no")).status == 404


def test_the_list_shows_waiting_proposals_first_with_what_they_cite_as_read_then(
    ground: Ground, desk: ProposalDesk
) -> None:
    answered = ground.propose(cited=())
    desk.decline("bob", answered, "not now")
    first, second = ground.propose(cited=()), ground.propose(robot="hal9000", binding="hal.yaml")
    listed = desk.listing()
    assert [p["id"] for p in listed] == [first, second, answered]  # the longest waiting first
    [cited] = listed[1]["cited"]
    assert (cited["then"], cited["now"]) == ({"value": 4.4, "state": "yellow"}, None)
    assert "no robot 'hal9000' here" in listed[1]["telemetry_error"]  # said, not hidden
    assert (listed[2]["state"], listed[2]["answer"]) == ("declined", "not now")


def test_an_acceptance_is_refused_while_the_proposal_is_not_what_would_run_and_the_proposal_stays_open(
    ground: Ground, desk: ProposalDesk
) -> None:
    forged = ground.propose(sha256="0" * 64)
    changed = refusal(lambda: desk.accept("alice", forged, "manual", onboard=False))
    assert changed.status == 409 and "the file is " in changed.message
    valued = ground.propose(inputs={"clean_filter_id": "CDRA-F-0012"})
    here = refusal(lambda: desk.accept("alice", valued, "manual", onboard=False))
    assert here.status == 409 and "they go up with a run on the habitat" in here.message
    with ground.log.engine.begin() as connection:  # withdrawn by its agent meanwhile
        connection.execute(update(agent_proposals).where(agent_proposals.c.id == valued).values(state="withdrawn"))
    assert "is withdrawn" in refusal(lambda: desk.accept("alice", valued, "manual", onboard=False)).message
    assert ground.store.get(forged).state == "open"  # type: ignore[union-attr]


def test_a_start_refused_opens_the_proposal_again_with_the_reason(ground: Ground, desk: ProposalDesk) -> None:
    control = RobotControl(ground.log.url)
    try:
        control.acquire("iva", "run-of-bob", "bob")  # another operator's run holds the robot
        proposal = ground.propose()
        refused = refusal(lambda: desk.accept("alice", proposal, "manual", onboard=False))
    finally:
        control.close()
    assert refused.status == 409 and "run-of-bob" in refused.message
    reopened = ground.store.get(proposal)
    assert reopened is not None
    assert (reopened.state, reopened.closed_by, reopened.run_id) == ("open", None, None)
    assert reopened.answer is not None and reopened.answer.startswith("not started by alice: ")


def test_a_runner_takes_only_the_proposal_its_user_accepted_for_what_it_runs_and_only_once(ground: Ground) -> None:
    setup = ground.setup()
    proposal = ground.propose(inputs={"clean_filter_id": "CDRA-F-0012"})

    def taken(user: str = "alice", values: dict[str, str] | None = None, pid: int = proposal) -> AcceptedProposal:
        found = proposal_taken(pid, ground.log, user, setup, {} if values is None else values)
        assert found is not None
        return found

    def not_runnable(**kwargs: Any) -> str:
        with pytest.raises(ProposalNotRunnable) as refused:
            taken(**kwargs)
        return str(refused.value)

    assert proposal_taken(None, ground.log, "alice", setup, {}) is None
    assert (
        not_runnable()
        == f"proposal {proposal} is open: only the operator who accepted it (alice has not) starts its run"
    )
    assert ground.store.close(proposal, "accepted", "alice")
    assert "accepted by alice" in not_runnable(user="bob")
    assert "disagrees" in not_runnable(values={"clean_filter_id": "CDRA-F-0013"})
    other = ground.propose(binding="iva-ground.yaml")
    assert ground.store.close(other, "accepted", "alice")
    assert "for binding iva-ground.yaml, not iva.yaml" in not_runnable(pid=other)
    values: dict[str, str] = {}
    accepted = taken(values=values)
    assert accepted == AcceptedProposal(proposal, "daphne", "cabin CO2 above its yellow limit")
    assert values == {"clean_filter_id": "CDRA-F-0012"}  # as --set gives it
    assert ground.store.get(proposal).run_id == setup.run_id  # type: ignore[union-attr]
    assert f"started run {setup.run_id} already" in not_runnable()  # one acceptance, one run


def test_a_unit_carries_the_accepted_proposal_and_reads_as_before_without_one() -> None:
    base: dict[str, Any] = {
        "run_id": "r-1",
        "procedure": "p.xml",
        "files": {"p.xml": "<procedure/>"},
        "binding": "iva.yaml",
        "user": "alice",
        "mode": "manual",
        "issued_at": 1.0,
        "expires_at": 2.0,
    }
    plain = Unit(**base)
    assert '"proposal"' not in plain.to_json() and Unit.from_json(plain.to_json()) == plain
    carried = Unit(**base, proposal=AcceptedProposal(7, "daphne", "CO2 high"))
    assert Unit.from_json(carried.to_json()) == carried
    forged = carried.to_json().replace('"id":7', '"id":"7"')
    with pytest.raises(UnitError, match="proposal.id must be an integer"):
        Unit.from_json(forged)
