"""What happened during a run: the records the audit log keeps and observers receive.

Every action of a run is one :class:`Event`, numbered per run. The executive creates them; the
audit log (:mod:`pride.audit_log`) stores them before anyone else sees them; reports and views
read them. Events are immutable: observing a run never changes it.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Protocol

__all__ = ["PAX", "Event", "EventKind", "Journal"]

#: The actor name of everything the automation does by itself.
PAX = "PAX"


class EventKind(str, enum.Enum):
    """The kinds of recorded action."""

    RUN_STARTED = "run_started"
    """A run began: procedure, mode, user."""
    RUN_RESUMED = "run_resumed"
    """A runner took over an interrupted run from its log."""
    RUN_COMPLETED = "run_completed"
    """The last instruction finished."""
    RUN_STOPPED = "run_stopped"
    """An operator stopped the run (it can be resumed)."""
    MODE_CHANGED = "mode_changed"
    """Manual ↔ autonomous."""
    INSTRUCTION_STARTED = "instruction_started"
    """An instruction became active (automation or operator began it)."""
    INSTRUCTION_COMPLETED = "instruction_completed"
    """An instruction finished successfully; data.next is where the run goes."""
    INSTRUCTION_FAILED = "instruction_failed"
    """An instruction failed; data.reason says why, data.next where the procedure branches (if it does)."""
    INSTRUCTION_SKIPPED = "instruction_skipped"
    """An operator skipped an instruction with a reason."""
    COMMAND_SENT = "command_sent"
    """A command went to a system, with its arguments."""
    COMMAND_RESULT = "command_result"
    """A system answered a command."""
    TELEMETRY_SEEN = "telemetry_seen"
    """The telemetry value a verify, wait or branch decided on."""
    OPERATOR_INPUT = "operator_input"
    """An operator entered a recorded value."""
    CONFIRMATION = "confirmation"
    """An operator confirmed a hazardous command."""
    AWAITING_OPERATOR = "awaiting_operator"
    """Automation holds at an instruction until an operator acts; data.reason says why."""
    PAUSED = "paused"
    """An operator paused automation."""
    CONTINUED = "continued"
    """An operator let automation continue."""
    BREAKPOINT_SET = "breakpoint_set"
    """An operator set a breakpoint."""
    BREAKPOINT_CLEARED = "breakpoint_cleared"
    """An operator removed a breakpoint."""
    BREAKPOINT_HIT = "breakpoint_hit"
    """Automation reached a breakpoint."""
    RETRY = "retry"
    """An operator asked to perform a failed or interrupted instruction again."""
    CALL_ENTERED = "call_entered"
    """A sub-procedure started with its inputs."""


@dataclass(frozen=True)
class Event:
    """One recorded action. ``instruction`` is the full number, e.g. ``2.3`` or ``3.1/1.2`` in a sub-procedure."""

    run_id: str
    seq: int
    kind: EventKind
    actor: str
    instruction: str | None = None
    data: dict[str, Any] = field(default_factory=dict)
    time: datetime = field(default_factory=lambda: datetime.now(UTC))

    def to_dict(self) -> dict[str, Any]:
        return {
            "run_id": self.run_id, "seq": self.seq, "kind": self.kind.value, "actor": self.actor,
            "instruction": self.instruction, "data": self.data, "time": self.time.isoformat(),
        }


class Journal(Protocol):
    """Where a run's events go first, durably, before the run proceeds."""

    def append(self, event: Event) -> None:
        """Store the event durably; raise if it could not be stored (the run must not go on unrecorded).

        May block while the store is unreachable (the audit log waits out an outage, up to its
        budget), so the caller's next action waits for the record, as it must.
        """
