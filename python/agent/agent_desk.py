"""What an agent may do, and only that: read procedures and runs, propose a run, withdraw it, ask for a halt.

The desk is the agent's whole reach into the ground: the MCP server (:mod:`agent.mcp_server`)
offers each of its public methods as a tool, and nothing else. There is no method to start,
approve, answer a record, confirm, take control, change a mode or correct a record: those acts
are not refused here, they do not exist for an agent. What an agent asks that the rules do not
allow raises :class:`AgentRefused` naming the rule, which the server records and returns.

Procedures are read as the consoles read them (the same folders, :class:`console.catalog.Catalog`)
and a version is what :func:`records.releases.procedure_digest` says, so an agent proposes exactly
what an operator would start. A halt goes to the console hosting the run that controls the robot,
as another console's HALT does (:mod:`ground.action_requests`), under the agent's id.
"""

from __future__ import annotations

import itertools
import os
import socket
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy import select

from console.actions import ActionRefused
from console.catalog import Catalog
from console.robot_telemetry import RobotTelemetry, TelemetryFacts, TelemetryRefused
from datafile import DataFileError
from ground.action_requests import ActionRequests, Answer, ForwardedAction
from ground.change_feed import ChangeFeed, open_change_feed
from ground.run_hosts import live_runs
from pride.event_words import describe_event
from pride.events import Event, EventKind
from pride.gateways import open_gateway
from pride.phrasing import Wording
from pride.report import summarize
from pride.run_setup import load_sysreps
from pride.systems import SystemGateway
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import CheckedProcedure, check_procedure
from procedure_language.model import RecordInstruction
from procedure_language.sysrep import SysRep, check_value
from records.agent_proposals import CitedTelemetry, NewProposal, Proposal, ProposalStore
from records.audit_log import AuditLog
from records.console_tables import run_hosts
from records.refusals import Refused
from records.releases import ReleaseStore, procedure_digest, short
from records.robot_control import RobotControl

__all__ = ["AgentDesk", "AgentRefused", "ProcedureFacts", "RunFacts", "TelemetryFacts"]

#: How many of a run's latest records an explanation quotes.
RECENT = 12
#: How many runs, newest first, a listing gives.
LISTED_RUNS = 50
_hosts = itertools.count(1)


class AgentRefused(Refused):
    """An agent's request the rules do not allow; ``rule`` names the rule, the message says why."""


@dataclass(frozen=True)
class ProcedureFacts:
    """A released procedure as an agent sees it."""

    file: str
    checked: CheckedProcedure
    sha256: str
    release: int
    released_by: str


@dataclass(frozen=True)
class RunFacts:
    """A run's records, folded as the after-action report folds them."""

    run_id: str
    events: list[Event]
    wording: Wording
    live: bool = False  # hosted now (a lease renewed): a run without an end is running, not interrupted


class AgentDesk:
    """One agent's reach into one ground database and the consoles' folders."""

    def __init__(
        self,
        agent: str,
        audit: AuditLog,
        catalog: Catalog,
        proposals: ProposalStore,
        rosbridge_urls: Mapping[str, str] | None = None,
        gateways: Callable[..., SystemGateway] = open_gateway,
    ) -> None:
        self.agent = agent
        self.robot_telemetry = RobotTelemetry(catalog, rosbridge_urls, gateways)
        self.audit = audit
        self.catalog = catalog
        self.proposals = proposals
        self.releases = ReleaseStore(audit.engine)
        self.control = RobotControl(audit.url)
        self._feed: ChangeFeed | None = None
        self._actions: ActionRequests | None = None

    def close(self) -> None:
        self.robot_telemetry.close()
        if self._actions is not None:
            self._actions.close()
        if self._feed is not None:
            self._feed.close()
        self.control.close()

    # ---- procedures ---------------------------------------------------------------------------
    def released_procedures(self) -> list[ProcedureFacts]:
        """The procedures of the consoles' folder whose current file is a released version."""
        facts = []
        for name in self.catalog.procedure_files():
            try:
                fact = self.released(name)
            except AgentRefused:
                continue  # a draft, a changed file or one with problems: nothing an agent may propose
            facts.append(fact)
        return facts

    def released(self, name: str) -> ProcedureFacts:
        """The procedure file ``name`` if its current version is released; AgentRefused says why not."""
        try:
            path = self.catalog.procedure_path(name)
        except ActionRefused as exc:
            raise AgentRefused("known_procedure", exc.message) from None
        try:
            checked = check_procedure(path, load_sysreps(self.catalog.sysreps))
        except (ProcedureError, DataFileError) as exc:
            raise AgentRefused("valid_procedure", f"{name} has problems and cannot run:\n{exc}") from None
        sha = procedure_digest(checked)
        state = self.releases.state(checked.procedure.id, sha)
        release = state.release
        if release is None:
            raise AgentRefused("released_version", f"{name} is a draft (never released): only a released version runs")
        if not state.released:
            raise AgentRefused(
                "released_version",
                f"{name} changed since release {release.number} (sha256 {short(release.sha256)} → {short(sha)}): "
                "the current file is a draft until it is released again",
            )
        return ProcedureFacts(name, checked, sha, release.number, release.released_by)

    def robots(self) -> dict[str, str]:
        """Robot name → the binding file that reaches it, from the consoles' bindings folder."""
        return self.robot_telemetry.robots()

    def binding_of(self, robot: str) -> str:
        """The binding file that reaches ``robot``; AgentRefused (known_robot) when there is none."""
        try:
            return self.robot_telemetry.binding_of(robot)
        except TelemetryRefused as exc:
            raise AgentRefused(exc.rule, exc.message) from None

    def sysrep(self, sysrep_id: str) -> SysRep:
        """The SysRep ``sysrep_id`` of the consoles' folders; AgentRefused (known_sysrep) when there is none."""
        sysreps = load_sysreps(self.catalog.sysreps)
        if sysrep_id not in sysreps:
            raise AgentRefused(
                "known_sysrep", f"no SysRep {sysrep_id!r} here (SysReps: {', '.join(sorted(sysreps)) or 'none'})"
            )
        return sysreps[sysrep_id]

    # ---- telemetry ----------------------------------------------------------------------------
    def telemetry(self, robot: str) -> list[TelemetryFacts]:
        """Every telemetry item ``robot``'s binding serves: its value now, how old, against its limits.

        The robot is read as a console reads it (:mod:`console.robot_telemetry`); an item not heard
        from yet has no value, and says so.
        """
        try:
            return self.robot_telemetry.read(robot)
        except TelemetryRefused as exc:
            raise AgentRefused(exc.rule, exc.message) from None

    # ---- runs ---------------------------------------------------------------------------------
    def runs(self) -> list[RunFacts]:
        """The newest runs first, at most :data:`LISTED_RUNS`."""
        wording = self.wording()
        newest = [run_id for run_id, _, _ in self.audit.runs()][-LISTED_RUNS:][::-1]
        live = live_runs(self.audit.engine, newest)
        return [RunFacts(run_id, self.audit.events(run_id), wording, run_id in live) for run_id in newest]

    def run(self, run_id: str) -> RunFacts:
        events = self.audit.events(run_id) if run_id else []
        if not events:
            raise AgentRefused("known_run", f"no run {run_id!r} in the record (list_runs names them)")
        return RunFacts(run_id, events, self.wording(), bool(live_runs(self.audit.engine, [run_id])))

    def wording(self) -> Wording:
        try:
            return Wording(load_sysreps(self.catalog.sysreps))
        except DataFileError:
            return Wording()  # ids as words: the records still read

    # ---- proposals ----------------------------------------------------------------------------
    def propose(
        self,
        procedure: str,
        sha256: str,
        robot: str,
        inputs: dict[str, Any],
        reason: str,
        cited: Sequence[str] = (),
    ) -> Proposal:
        """Propose a run of the released ``procedure`` (its version ``sha256``) on ``robot``,
        citing the telemetry items ``cited`` (``system.item``), read now and kept with it."""
        if not reason.strip():
            raise AgentRefused("reason_given", "a proposal gives its reason in words, for the operator who answers it")
        facts = self.released(procedure)
        if sha256 != facts.sha256:
            older = [r for r in self.releases.releases() if r.procedure == facts.checked.procedure.id]
            match = next((r for r in older if r.sha256 == sha256), None)
            raise AgentRefused(
                "released_version",
                f"{procedure}: sha256 {short(sha256)} is "
                + (f"release {match.number}, no longer the current one" if match else "no version ever released")
                + f"; its released version is release {facts.release}, sha256 {facts.sha256}",
            )
        binding = self.binding_of(robot)
        holder = self.control.holder(robot)
        if holder is not None:
            raise AgentRefused(
                "one_run_per_robot",
                f"{robot} is controlled by {holder.describe()}: a run proposed now could not start on it",
            )
        checked_inputs = {name: _checked_input(facts.checked, name, value) for name, value in inputs.items()}
        citations = self._cite(robot, cited)
        new = NewProposal(
            self.agent,
            facts.checked.procedure.id,
            procedure,
            facts.sha256,
            facts.release,
            robot,
            binding,
            checked_inputs,
            reason.strip(),
            citations,
        )
        return self.proposals.propose(new)

    def _cite(self, robot: str, cited: Sequence[str]) -> tuple[CitedTelemetry, ...]:
        """The items ``cited`` as ``robot`` reports them now; AgentRefused (known_telemetry) names
        one it does not serve."""
        if not cited:
            return ()
        facts = {f"{fact.system}.{fact.item.id}": fact for fact in self.telemetry(robot)}
        unknown = [name for name in cited if name not in facts]
        if unknown:
            raise AgentRefused(
                "known_telemetry",
                f"{robot} serves no telemetry {', '.join(map(repr, unknown))} "
                "(cite items as SYSTEM.ITEM from read_telemetry)",
            )
        return tuple(
            CitedTelemetry(facts[name].system, facts[name].item.id, facts[name].value, facts[name].state)
            for name in dict.fromkeys(cited)
        )

    def withdraw(self, proposal_id: int) -> Proposal:
        proposal = self.proposals.get(proposal_id)
        if proposal is None or proposal.proposed.agent != self.agent:
            raise AgentRefused(
                "own_proposal", f"{self.agent} has no proposal {proposal_id} (an agent withdraws its own)"
            )
        if not self.proposals.close(proposal_id, "withdrawn", self.agent):
            current = self.proposals.get(proposal_id)
            raise AgentRefused("open_proposal", f"proposal {proposal_id} is {current.state if current else 'gone'}")
        withdrawn = self.proposals.get(proposal_id)
        assert withdrawn is not None
        return withdrawn

    # ---- halt ---------------------------------------------------------------------------------
    def halt(self, robot: str, reason: str) -> tuple[str, Answer]:
        """Ask the console hosting the run that controls ``robot`` to HALT it, as the agent: (run id, its answer)."""
        if not reason.strip():
            raise AgentRefused("reason_given", "a halt request gives its reason in words")
        self.binding_of(robot)  # known_robot
        holder = self.control.holder(robot)
        if holder is None:
            raise AgentRefused("run_state", f"no run controls {robot}: there is nothing to halt")
        with self.audit.engine.connect() as connection:
            host_id = connection.scalar(select(run_hosts.c.host_id).where(run_hosts.c.run_id == holder.run_id))
        if host_id is None:
            raise AgentRefused(
                "hosted_run",
                f"run {holder.run_id} on {robot} is not hosted by a console (a caretaker run on a command line): "
                "halt it there",
            )
        action = {"action": "halt", "reason": f"halt asked by agent {self.agent}: {reason.strip()}"}
        return holder.run_id, self._forwarder().forward(holder.run_id, str(host_id), self.agent, action)

    def _forwarder(self) -> ActionRequests:
        """Forwarding through the database, as a console without runs of its own forwards (made at first use)."""
        if self._actions is None:
            host_id = f"agent-{self.agent}-{socket.gethostname()}-{os.getpid()}-{next(_hosts)}"[:64]
            self._actions = ActionRequests(
                self.audit.engine, host_id=host_id, console=f"agent {self.agent}", perform=_hosts_nothing
            )
            self._feed = open_change_feed(self.audit.engine)
            self._feed.subscribe(self._actions.notice)
        return self._actions


def _hosts_nothing(request: ForwardedAction) -> Answer:
    """An agent hosts no run: no request is ever addressed to it."""
    return Answer(404, {"error": f"run {request.run_id} is not hosted by an agent"})


def _checked_input(checked: CheckedProcedure, name: str, value: Any) -> Any:
    """A proposed value for the procedure's input or record ``name``, checked as the run would check it."""
    procedure = checked.procedure
    declared = next((i for i in procedure.inputs if i.name == name), None)
    records = [i for i in procedure.instructions if isinstance(i, RecordInstruction) and i.name == name]
    if declared is None and not records:
        names = [i.name for i in procedure.inputs] + sorted(
            {i.name for i in procedure.instructions if isinstance(i, RecordInstruction)}
        )
        raise AgentRefused(
            "known_input", f"{procedure.id} has no input or record {name!r} (it has: {', '.join(names)})"
        )
    try:
        if declared is not None:
            return check_value(name, declared.type, value)
        for record in records:
            value = record.check(value)
        return value
    except ValueError as exc:
        raise AgentRefused("input_pattern", f"{exc}") from None


def run_words(events: list[Event], wording: Wording, live: bool = False) -> dict[str, Any]:
    """A run in the report's words: what it is, how it went (``running`` when ``live`` and not
    ended), where it is and what it waits for."""
    summary = summarize(events)
    outcome = "running" if live and summary.outcome == "interrupted" else summary.outcome
    last = events[-1]
    waiting = (
        describe_event(last, wording)
        if last.kind in (EventKind.AWAITING_OPERATOR, EventKind.APPROVAL_REQUESTED)
        else ""
    )
    at = next((e.instruction for e in reversed(events) if e.instruction), None)
    return {
        "run_id": summary.run_id,
        "procedure": summary.procedure,
        "title": summary.title,
        "version": summary.released,
        "started": summary.started.isoformat(),
        "started_by": summary.started_by,
        "outcome": outcome,
        "at_instruction": at if outcome != "completed" else None,
        "waiting_for": waiting,
        "steps": [
            {"number": s.number, "title": s.title, "completed": s.completed, "failed": s.failed, "skipped": s.skipped}
            for s in summary.steps
        ],
        "recent": [
            {"seq": e.seq, "time": e.time.isoformat(), "actor": e.actor, "words": describe_event(e, wording)}
            for e in events[-RECENT:]
        ],
        "monitors": summary.monitors,
    }
