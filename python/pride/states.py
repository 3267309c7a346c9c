"""The states of a run an observer can see: modes, run and instruction states, holds, snapshots.

Kept apart from :mod:`pride.executive` so views and reports can name them without the machinery.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from datetime import datetime
from typing import Any

__all__ = [
    "CarriedApprovalSpent",
    "Controller",
    "Hold",
    "InstructionStatus",
    "JournalFailure",
    "Mode",
    "OperatorActionError",
    "RecordNotCheckable",
    "RefusalRule",
    "RunEnded",
    "RunStatus",
    "Snapshot",
]


class Mode(enum.Enum):
    """Who drives the run."""

    MANUAL = "manual"
    """The operator performs every instruction."""
    AUTONOMOUS = "autonomous"
    """PAX performs automatable instructions and holds for the operator where needed."""


class RunStatus(enum.Enum):
    """Where the run is in its life."""

    READY = "ready"
    """Created, not started."""
    ACTIVE = "active"
    """Started and not finished."""
    COMPLETED = "completed"
    """Every instruction on the path was completed or skipped."""
    STOPPED = "stopped"
    """An operator stopped it (or recording failed); it can be resumed from the log."""


class InstructionStatus(enum.Enum):
    """The state of one instruction in this run."""

    PENDING = "pending"
    """Not reached yet."""
    ACTIVE = "active"
    """The current instruction, waiting to be performed."""
    EXECUTING = "executing"
    """Being performed (command sent, telemetry watched, sub-procedure running)."""
    COMPLETED = "completed"
    """Done successfully."""
    FAILED = "failed"
    """Performed and failed."""
    SKIPPED = "skipped"
    """An operator skipped it with a reason."""
    HALTED = "halted"
    """A halt ended it before it finished (never completed); retry performs it again."""
    OUTCOME_UNKNOWN = "outcome_unknown"
    """Its command may or may not have been executed: an operator asks again, records, or skips."""


class Hold(enum.Enum):
    """Why automation is not performing the current instruction."""

    OPERATOR_INPUT = "operator_input"
    """A record: an operator must enter a value."""
    OPERATOR_ACTION = "operator_action"
    """A manual instruction: an operator must do it and mark it done."""
    NOT_AUTOMATABLE = "not_automatable"
    """The author marked it automatable=false: an operator must perform it."""
    CONFIRMATION = "confirmation"
    """A hazardous command: an operator must confirm it before it is sent (under critical
    commanding: an operator must send it for a second operator's approval)."""
    APPROVAL = "approval"
    """A command sent for approval: a second operator must approve it (:mod:`pride.approvals`)."""
    BREAKPOINT = "breakpoint"
    """A breakpoint: an operator must continue or step."""
    PAUSED = "paused"
    """An operator paused automation."""
    FAILURE = "failure"
    """It failed and the procedure has no branch for that: retry or skip."""
    IN_FLIGHT = "in_flight"
    """A log written before command keys: it was in flight when the runner died, retry (resend) or skip.
    (A keyed command in flight at a crash is re-sent with its key by itself on resume.)"""
    MANUAL_MODE = "manual_mode"
    """Manual mode: the operator performs every instruction."""
    OUTCOME_UNKNOWN = "outcome_unknown"
    """Its command's outcome could not be learnt: ask again (same key), record what the system
    shows (succeeded or failed, with a reason), or skip it with a reason."""
    HALTED = "halted"
    """An operator halted the run: retry (a new attempt), continue, skip, or stop. After a halted
    motion whose plan ended with it (:mod:`pride.replanning`) retry and continue cannot work:
    re-plan from where the arm is and go on, go back, skip, or stop."""
    CONTROL_LOST = "control_lost"
    """Another run took control of the robot: this run sends nothing until control is taken back."""


class RefusalRule(enum.Enum):
    """The rule that refused an operator's act, named in its ``action_refused`` record."""

    TWO_PERSON = "two_person"
    """Nobody approves their own command: a second operator must (:mod:`pride.approvals`)."""
    OBSERVERS_WATCH = "observers_watch"
    """An observer may watch a run, not act on it."""
    CURRENT_INSTRUCTION = "current_instruction"
    """An act clicked on an instruction applies to it only while the run is there."""
    RUN_STATE = "run_state"
    """The act does not apply to the run as it is now (the executive says why)."""
    VALID_PROCEDURE = "valid_procedure"
    """A procedure with problems never starts."""
    RELEASED_VERSION = "released_version"
    """A run runs a released version; a draft or a changed file only as a rehearsal on a simulator."""
    ONE_RUN_PER_ROBOT = "one_run_per_robot"
    """One run controls a robot; another takes it over only with a reason."""
    BINDING_SERVES = "binding_serves"
    """A run starts only on a binding that serves every system its procedure uses."""
    ONE_SUPERVISOR = "one_supervisor"
    """An onboard run has one supervising runner: another attaches only once it is gone."""


class OperatorActionError(RuntimeError):
    """An operator action does not apply to the run's current state; the message says why.

    ``rule``: the rule that refused it; ``recorded``: the executive already recorded the refusal
    (an ``action_refused`` event), so whoever passes it on does not record it twice.
    """

    def __init__(self, message: str, *, rule: RefusalRule = RefusalRule.RUN_STATE, recorded: bool = False) -> None:
        super().__init__(message)
        self.rule = rule
        self.recorded = recorded


class RunEnded(OperatorActionError):
    """The run has ended, or is being stopped: another console, host or thread ended it first.
    Someone who meant to end it too has nothing left to do."""


class CarriedApprovalSpent(OperatorActionError):
    """An approval carried with an onboard unit that can no longer send its command: it ran out, or
    it approves another sender's. Unlike a refusal of the run's state of the moment, it will not
    change: the command waits for a live approval from the ground."""


class RecordNotCheckable(OperatorActionError):
    """A record's value could not be checked against the telemetry it must be one of: the report
    is stale or missing, or reading it failed. Unlike a value refused for what it is, the same
    value may be accepted once ``system`` reports ``item`` again (after a lost link, a restart)."""

    def __init__(self, message: str, system: str, item: str) -> None:
        super().__init__(message)
        self.system = system
        self.item = item


class JournalFailure(OperatorActionError):
    """The audit log could not store an event: the run stopped at once (resume it once the log is back)."""


@dataclass(frozen=True)
class Controller:
    """The run that controls a robot: only it may send the robot commands."""

    robot: str
    run_id: str
    user: str
    since: datetime
    reason: str = ""  # why it took control from another run (empty when it simply took it)

    def describe(self) -> str:
        return f"run {self.run_id} (user {self.user}, since {self.since:%Y-%m-%d %H:%M:%S}Z)"


@dataclass(frozen=True)
class Snapshot:
    """The observable state of a run at one moment.

    Link and journal fields are read live, even while the run waits for the audit log (then the
    rest is the state from before that wait).
    """

    run_id: str
    procedure_id: str
    status: RunStatus
    mode: Mode
    current: str | None
    hold: Hold | None
    reason: str
    executing: bool
    statuses: dict[str, InstructionStatus]
    breakpoints: frozenset[str]
    variables: dict[str, Any]
    last_seq: int
    error: str | None = None
    robot: str = ""
    has_control: bool = False  # this run controls its robot (False when taken over, or without control)
    unknown_key: str | None = None  # the command whose outcome is unknown (Hold.OUTCOME_UNKNOWN)
    halted_by: str | None = None  # who halted the run (Hold.HALTED), and why
    halt_reason: str = ""
    replan_from: str | None = None  # after a halted motion: the instruction that plans it again (the way on)
    no_retry: str = ""  # why sending the held instruction again cannot work, and what can ("" when it can)
    approval: dict[str, Any] | None = None  # the current command's approval request or approval (JSON)
    link_lost_since: datetime | None = None  # a robot link is down since then (UTC)
    commands_in_flight: int = 0  # while it is down: commands waiting for their outcome
    link_quiet: bool = False  # down only in that nothing came from it for a few keepalive intervals
    journal_available: bool = True  # the audit log takes appends now
    journal_unavailable_since: datetime | None = None
    journal_error: str = ""

    def to_json(self) -> dict[str, Any]:
        """The state as views draw it (JSON types): status, mode, current instruction, hold, links."""
        return {
            "run_id": self.run_id,
            "procedure": self.procedure_id,
            "status": self.status.value,
            "mode": self.mode.value,
            "current": self.current,
            "hold": self.hold.value if self.hold else None,
            "reason": self.reason,
            "executing": self.executing,
            "statuses": {n: s.value for n, s in self.statuses.items()},
            "breakpoints": sorted(self.breakpoints),
            "variables": self.variables,
            "error": self.error,
            "last_seq": self.last_seq,
            "robot": self.robot,
            "has_control": self.has_control,
            "unknown_key": self.unknown_key,
            "halted_by": self.halted_by,
            "halt_reason": self.halt_reason,
            "replan_from": self.replan_from,
            "no_retry": self.no_retry,
            "approval": self.approval,
            "link": {
                "state": "lost",
                "since": self.link_lost_since.isoformat(),
                "in_flight": self.commands_in_flight,
                "quiet": self.link_quiet,
            }
            if self.link_lost_since
            else {"state": "connected"},
            "journal": {
                "available": self.journal_available,
                "error": self.journal_error,
                "since": self.journal_unavailable_since.isoformat() if self.journal_unavailable_since else None,
            },
        }

    def link_summary(self) -> str:
        """ "link lost since T, N commands in flight" ("no news since T" while the link is only
        quiet), or "" while the links are up."""
        if self.link_lost_since is None:
            return ""
        n = self.commands_in_flight
        what = "no news" if self.link_quiet else "link lost"
        return f"{what} since {self.link_lost_since:%H:%M:%S}Z, {n} command{'' if n == 1 else 's'} in flight"

    def journal_summary(self) -> str:
        """ "audit log unavailable since T: error", or "" while it takes appends."""
        if self.journal_available:
            return ""
        since = f" since {self.journal_unavailable_since:%H:%M:%S}Z" if self.journal_unavailable_since else ""
        return f"audit log unavailable{since}: {self.journal_error} (the run waits for it)"
