"""The states of a run an observer can see: modes, run and instruction states, holds, snapshots.

Kept apart from :mod:`pride.executive` so views and reports can name them without the machinery.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

__all__ = ["Hold", "InstructionStatus", "Mode", "OperatorActionError", "RunStatus", "Snapshot"]


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


class Hold(enum.Enum):
    """Why automation is not performing the current instruction."""

    OPERATOR_INPUT = "operator_input"
    """A record: an operator must enter a value."""
    OPERATOR_ACTION = "operator_action"
    """A manual instruction: an operator must do it and mark it done."""
    NOT_AUTOMATABLE = "not_automatable"
    """The author marked it automatable=false: an operator must perform it."""
    CONFIRMATION = "confirmation"
    """A hazardous command: an operator must confirm it before it is sent."""
    BREAKPOINT = "breakpoint"
    """A breakpoint: an operator must continue or step."""
    PAUSED = "paused"
    """An operator paused automation."""
    FAILURE = "failure"
    """It failed and the procedure has no branch for that: retry or skip."""
    IN_FLIGHT = "in_flight"
    """It was in flight when the runner died: retry (resend) or skip."""
    MANUAL_MODE = "manual_mode"
    """Manual mode: the operator performs every instruction."""


class OperatorActionError(RuntimeError):
    """An operator action does not apply to the run's current state; the message says why."""


@dataclass(frozen=True)
class Snapshot:
    """The observable state of a run at one moment."""

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
