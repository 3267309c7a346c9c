"""What happened during a run: the records the audit log keeps and observers receive.

Every action of a run is one :class:`Event`, numbered per run. The executive creates them; the
audit log (:mod:`records.audit_log`) stores them before anyone else sees them; reports and views
read them. Events are immutable: observing a run never changes it.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Protocol

__all__ = ["PAX", "Availability", "Event", "EventKind", "Journal"]

#: The actor name of everything the automation does by itself.
PAX = "PAX"


class EventKind(str, enum.Enum):
    """The kinds of recorded action."""

    RUN_STARTED = "run_started"
    """A run began: procedure, mode, user."""
    RUN_RESUMED = "run_resumed"
    """A runner took over an interrupted run from its log."""
    RUN_COMPLETED = "run_completed"
    """The last instruction finished; the actor is whoever finished it (PAX, or the operator)."""
    RUN_STOPPED = "run_stopped"
    """An operator stopped the run (it can be resumed): a command in flight was cancelled first
    (data.cancel: what the system answered), data.reason the operator's words."""
    MODE_CHANGED = "mode_changed"
    """Manual ↔ autonomous."""
    INSTRUCTION_STARTED = "instruction_started"
    """An instruction became active (automation or operator began it): data.instruction_kind,
    data.text (its sentence as the procedure view shows it: the author's, else made from the
    SysRep's labels; ``${...}`` as written) and data.text_filled (that sentence with the values
    known then filled in; events recorded before it existed lack it)."""
    INSTRUCTION_COMPLETED = "instruction_completed"
    """An instruction finished successfully; data.next is where the run goes."""
    INSTRUCTION_FAILED = "instruction_failed"
    """An instruction failed; data.reason says why, data.next where the procedure branches (if it does)."""
    INSTRUCTION_SKIPPED = "instruction_skipped"
    """An operator skipped an instruction with a reason."""
    INSTRUCTION_HALTED = "instruction_halted"
    """A halt (or stop) ended an instruction before it finished: never completed. The actor is who
    halted it; data.reason their words, data.next the instruction (it is performed again on retry)."""
    COMMAND_SENT = "command_sent"
    """A command went to a system: data.key (``run/instruction/attempt``), args, hazardous,
    confirmed_by (who confirmed a hazardous one), requested_by and approved_by (the sender and the
    second operator of a command that needed approval), resend (the same key sent again)."""
    COMMAND_RESULT = "command_result"
    """A system answered a command: data.key, data.outcome (succeeded, failed, unknown, halted),
    success (True, False, or None while the outcome is unknown), message, values."""
    OUTCOME_RESOLVED = "outcome_resolved"
    """An operator recorded what became of a command of unknown outcome after checking the system:
    data.key, data.outcome (succeeded or failed), data.reason."""
    HALT = "halt"
    """An operator halted the run: the command in flight was cancelled (data.key; data.cancel what
    the system answered) and automation holds; data.reason their words."""
    LINK_LOST = "link_lost"
    """The link to the robot dropped (actor PAX): data.link, data.since, data.in_flight. The run
    waits (commands in flight are re-sent when it is back, within the outage budget)."""
    LINK_RESTORED = "link_restored"
    """The link is back (actor PAX): data.link, data.since (when it was lost), data.seconds."""
    CONTROL_TAKEN = "control_taken"
    """This run took control of its robot from another run: data.robot, data.from_run,
    data.from_user, data.reason."""
    CONTROL_LOST = "control_lost"
    """Another run took control of this run's robot (actor PAX): data.robot, data.by_run,
    data.by_user, data.reason. The run holds and sends nothing more."""
    RECORD_CORRECTED = "record_corrected"
    """An operator re-entered an earlier record: data.name, data.old, data.value, data.reason."""
    STEPPED_BACK = "stepped_back"
    """An operator went back to an earlier instruction of the step: data.from, data.next (where the
    run continues), data.reset (instructions to be performed again), data.reason."""
    TELEMETRY_SEEN = "telemetry_seen"
    """The telemetry value a verify, wait or branch decided on."""
    OPERATOR_INPUT = "operator_input"
    """An operator entered a recorded value."""
    CONFIRMATION = "confirmation"
    """An operator confirmed a hazardous command."""
    APPROVAL_REQUESTED = "approval_requested"
    """An operator (the sender) asked for a command that needs a second operator's approval to be
    sent (:mod:`pride.approvals`): data.command (in words), data.level."""
    APPROVAL_GIVEN = "approval_given"
    """A second operator approved it (the actor): data.sender, data.command, data.expires (UTC);
    it is sent at once, its command_sent naming both."""
    APPROVAL_EXPIRED = "approval_expired"
    """An approval ran out before its command could be sent (actor PAX): data.approver,
    data.sender, data.expired; nothing was sent and the command waits for a new approval."""
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
    """An operator asked to perform a failed, halted or interrupted instruction again (a new
    attempt, a new key), or with data.same_key to ask again about a command of unknown outcome
    (data.key re-sent: the habitat answers its outcome or joins it, never runs it twice)."""
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
            "run_id": self.run_id,
            "seq": self.seq,
            "kind": self.kind.value,
            "actor": self.actor,
            "instruction": self.instruction,
            "data": self.data,
            "time": self.time.isoformat(),
        }


@dataclass(frozen=True)
class Availability:
    """Whether appends reach the journal's store; ``since`` is when the current outage began (UTC)."""

    available: bool
    since: datetime | None = None
    error: str = ""


class Journal(Protocol):
    """Where a run's events go first, durably, before the run proceeds."""

    def append(self, event: Event) -> None:
        """Store the event durably; raise if it could not be stored (the run must not go on unrecorded).

        May block while the store is unreachable (the audit log waits out an outage, up to its
        budget), so the caller's next action waits for the record, as it must.
        """

    @property
    def availability(self) -> Availability:
        """Whether appends reach the store now (read without waiting, during an outage too)."""
