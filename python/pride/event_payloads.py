"""What each kind of event records: one frozen dataclass per :class:`pride.event_kinds.EventKind`.

Each class's docstring is the contract of its kind's ``data``: the audit log, replay, the
downlink, the console, the terminal and the report read these fields and nothing else, and fold
events with one ``match`` over :data:`Payload` ending in ``typing.assert_never``, so a kind added
here and forgotten by a fold fails mypy (the monitors' payloads are in :mod:`pride.monitor_events`).
How a payload is stored as JSON and read back, the same byte for byte, is :mod:`pride.event_json`'s.
"""

from __future__ import annotations

import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeAlias

from pride.event_json import JSON_NAME, EventDataError, Recorded, optional, read_payload
from pride.event_kinds import EventKind
from pride.monitor_events import MonitorCleared, MonitorViolated, WentTo

__all__ = [
    "ActionRefused",
    "ApprovalExpired",
    "ApprovalGiven",
    "ApprovalRequested",
    "AwaitingOperator",
    "BreakpointCleared",
    "BreakpointHit",
    "BreakpointSet",
    "CallEntered",
    "CallReturned",
    "CommandResult",
    "CommandSent",
    "Confirmation",
    "Continued",
    "ControlLost",
    "ControlTaken",
    "EventDataError",
    "Halt",
    "InstructionCompleted",
    "InstructionFailed",
    "InstructionHalted",
    "InstructionSkipped",
    "InstructionStarted",
    "LinkLost",
    "LinkRestored",
    "MonitorCleared",
    "MonitorViolated",
    "ModeChanged",
    "OperatorInput",
    "OutcomeResolved",
    "Paused",
    "Payload",
    "RecordCorrected",
    "Retry",
    "RunCompleted",
    "RunResumed",
    "RunStarted",
    "RunStopped",
    "SteppedBack",
    "SupervisorAttached",
    "TelemetrySeen",
    "ValueSet",
    "WentTo",
    "payload_from_json",
]


# ---- the run --------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class RunStarted(Recorded):
    """A run began (the actor started it).

    ``procedure``, ``title``, ``version``, ``path`` (the file, resolved): what it runs; ``mode``
    (``manual`` or ``autonomous``); ``robot``: the binding's robot; ``steps``: each step's
    ``number``, ``id`` and ``title``; ``section``, for a run of part of the procedure
    (:class:`pride.run_section.RunSection`): the step it started at (``from``), the step it stops
    after (``to``, null: the end) and the values given for what the steps before would have
    bound. With a recorded version (:mod:`pride.run_version`): ``sha256`` of the file, ``release``
    (its release number, null for a rehearsal) and ``rehearsal``; all three or none. ``proposal``,
    for a run an operator started by accepting an agent's proposal: its ``id``, ``agent`` and ``reason``.
    """

    KIND = EventKind.RUN_STARTED
    procedure: str
    title: str
    version: str
    path: str
    mode: str
    robot: str
    steps: tuple[Mapping[str, Any], ...]
    sha256: str | None = optional()
    release: int | None = optional()
    rehearsal: bool | None = optional()
    section: Mapping[str, Any] | None = optional()
    proposal: Mapping[str, Any] | None = optional()

    def _left_out(self) -> set[str]:
        versioned = {"sha256", "release", "rehearsal"} if self.sha256 is None else set()
        return versioned | {name for name in ("section", "proposal") if getattr(self, name) is None}

    def step_titles(self) -> tuple[tuple[int, str], ...]:
        """Each step's number and title, in order."""
        return tuple((int(step.get("number", 0)), str(step.get("title", ""))) for step in self.steps)


@dataclass(frozen=True, kw_only=True)
class RunResumed(Recorded):
    """A runner took over an interrupted run from its log: ``mode`` it goes on in; ``in_flight``:
    the instruction whose command had no answer nor key (a log from before command keys), else
    null; ``resend``: the key it sends again by itself (in flight at the interruption), else null."""

    KIND = EventKind.RUN_RESUMED
    mode: str
    in_flight: str | None
    resend: str | None


@dataclass(frozen=True, kw_only=True)
class RunCompleted(Recorded):
    """The last instruction finished; the actor is whoever finished it (PAX, or the operator).

    ``left_behind``: what the run added to its systems and still holds (``system``, ``name``,
    ``why``: :mod:`pride.leftovers`); ``taken_back``: names it removed. Each only when not empty.
    """

    KIND = EventKind.RUN_COMPLETED
    taken_back: tuple[str, ...] = optional(())
    left_behind: tuple[Mapping[str, Any], ...] = optional(())

    def leftovers(self) -> tuple[tuple[str, str, str], ...]:
        """What is left behind as (system, name, why)."""
        return _leftovers(self.left_behind)


@dataclass(frozen=True, kw_only=True)
class RunStopped(Recorded):
    """An operator stopped the run (it can be resumed unless it took something back).

    ``reason``: their words; ``key``: the command in flight, cancelled first (null: none);
    ``cancel``: what the system answered to that cancel (``stopped``, ``message``; null without
    one); ``taken_back`` and ``left_behind`` as in :class:`RunCompleted`.
    """

    KIND = EventKind.RUN_STOPPED
    reason: str
    key: str | None
    cancel: Mapping[str, Any] | None
    taken_back: tuple[str, ...] = optional(())
    left_behind: tuple[Mapping[str, Any], ...] = optional(())

    def leftovers(self) -> tuple[tuple[str, str, str], ...]:
        """What is left behind as (system, name, why)."""
        return _leftovers(self.left_behind)


@dataclass(frozen=True, kw_only=True)
class ModeChanged(Recorded):
    """Manual ↔ autonomous: ``mode`` is the new one (see :attr:`new_mode`)."""

    KIND = EventKind.MODE_CHANGED
    mode: str

    @property
    def new_mode(self) -> str:
        """The mode it changed to (the earliest runs recorded it as ``to``)."""
        return self.mode or str(self.extra.get("to", ""))


# ---- instructions ---------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class InstructionStarted(Recorded):
    """An instruction became active (automation or an operator began it).

    ``instruction_kind``: command, verify, ...; ``text``: its sentence as the procedure view shows
    it (the author's, else made from the SysRep's labels; ``${...}`` as written); ``text_filled``:
    that sentence with the values known then filled in (events recorded before it existed lack it).
    """

    KIND = EventKind.INSTRUCTION_STARTED
    instruction_kind: str
    text: str
    text_filled: str | None = optional()


@dataclass(frozen=True, kw_only=True)
class InstructionCompleted(Recorded):
    """An instruction finished successfully: ``next`` is where the run goes (``end``: the run is over);
    ``went_to``: the step a branch or go-to chose, when it chose one."""

    KIND = EventKind.INSTRUCTION_COMPLETED
    next: str
    went_to: str | None = optional()


@dataclass(frozen=True, kw_only=True)
class InstructionFailed(Recorded):
    """An instruction failed: ``reason`` says why; ``next`` is where the run goes (the instruction
    itself while it holds for an operator); ``branch``: the on-failure step it went to, if it did."""

    KIND = EventKind.INSTRUCTION_FAILED
    reason: str
    next: str
    branch: str | None = optional()


@dataclass(frozen=True, kw_only=True)
class InstructionSkipped(Recorded):
    """An operator skipped an instruction: ``reason`` their words, ``next`` where the run goes."""

    KIND = EventKind.INSTRUCTION_SKIPPED
    reason: str
    next: str


@dataclass(frozen=True, kw_only=True)
class InstructionHalted(Recorded):
    """A halt (or stop) ended an instruction before it finished: never completed. The actor is who
    halted it; ``reason`` their words, ``detail`` what the instruction was doing, ``next`` the
    instruction (it is performed again on retry)."""

    KIND = EventKind.INSTRUCTION_HALTED
    reason: str
    detail: str
    next: str


# ---- commands -------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class CommandSent(Recorded):
    """A command went to a system: ``system``, ``command``, ``args``; ``key`` (``run/instruction/
    attempt``, or ``run/operator/seq`` and ``run/take-back/seq`` for one outside the instructions);
    ``hazardous``; ``confirmed_by`` (who confirmed a hazardous one); ``requested_by`` and
    ``approved_by`` (the sender and the second operator of a command that needed approval);
    ``resend`` (the same key sent again); ``ad_hoc`` (an operator's command outside the
    instructions, no instruction number); ``take_back`` (the name of what a stop removes)."""

    KIND = EventKind.COMMAND_SENT
    system: str
    command: str
    args: Mapping[str, Any]
    key: str | None
    hazardous: bool
    resend: bool = optional(False)
    confirmed_by: str | None = optional()
    requested_by: str | None = optional()
    approved_by: str | None = optional()
    ad_hoc: bool = optional(False)
    take_back: str | None = optional()


@dataclass(frozen=True, kw_only=True)
class CommandResult(Recorded):
    """A system answered a command: ``system``, ``command``, ``args``, ``key`` as sent;
    ``outcome`` (succeeded, failed, unknown, halted); ``success`` (true, false, or null while the
    outcome is unknown); ``message``; ``values``; ``result``: the procedure's name for the result
    (null: unnamed), not written for a command outside the instructions (``ad_hoc``, with
    ``take_back`` as in :class:`CommandSent`)."""

    KIND = EventKind.COMMAND_RESULT
    system: str
    command: str
    args: Mapping[str, Any]
    key: str | None
    outcome: str
    success: bool | None
    message: str
    values: Mapping[str, Any]
    result: str | None = None
    ad_hoc: bool = optional(False)
    take_back: str | None = optional()

    def _left_out(self) -> set[str]:
        return super()._left_out() | ({"result"} if self.ad_hoc else set())


@dataclass(frozen=True, kw_only=True)
class OutcomeResolved(Recorded):
    """An operator recorded what became of a command of unknown outcome after checking the system:
    ``key``, ``outcome`` (succeeded or failed), ``reason`` (what they checked)."""

    KIND = EventKind.OUTCOME_RESOLVED
    key: str
    outcome: str
    reason: str


@dataclass(frozen=True, kw_only=True)
class Halt(Recorded):
    """An operator halted the run and automation holds: ``reason`` their words; ``key`` the command
    in flight, cancelled (null: none); ``cancel`` what the system answered (``stopped``,
    ``message``; null without a cancel); ``executing``: whether an instruction was being performed."""

    KIND = EventKind.HALT
    reason: str
    key: str | None
    cancel: Mapping[str, Any] | None
    executing: bool

    @property
    def cancel_message(self) -> str:
        """What the system answered to the cancel ("" without one)."""
        return str((self.cancel or {}).get("message") or "")


# ---- links and control ----------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class LinkLost(Recorded):
    """The link to the robot dropped (actor PAX). ``links``: the links down or quiet; ``since``
    (ISO UTC): when the first of them was last heard; ``in_flight``: commands waiting on them;
    ``quiet``: every such link is still connected, only nothing came from it. The run waits:
    commands in flight are re-sent when it is back, within the outage budget."""

    KIND = EventKind.LINK_LOST
    links: tuple[str, ...]
    since: str
    in_flight: int
    quiet: bool = False


@dataclass(frozen=True, kw_only=True)
class LinkRestored(Recorded):
    """The link is back (actor PAX): ``since`` (ISO UTC) when it was lost, ``seconds`` how long."""

    KIND = EventKind.LINK_RESTORED
    since: str
    seconds: float


@dataclass(frozen=True, kw_only=True)
class ControlTaken(Recorded):
    """This run took control of its robot from another run: ``robot``, ``from_run``,
    ``from_user``, ``reason`` (the actor's words)."""

    KIND = EventKind.CONTROL_TAKEN
    robot: str
    from_run: str
    from_user: str
    reason: str


@dataclass(frozen=True, kw_only=True)
class ControlLost(Recorded):
    """Another run took control of this run's robot (actor PAX): ``robot``, ``by_run`` and
    ``by_user`` (null when the holder is not known), ``reason`` (theirs). The run holds and sends
    nothing more."""

    KIND = EventKind.CONTROL_LOST
    robot: str
    by_run: str | None
    by_user: str | None
    reason: str


# ---- operators' entries -----------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class TelemetrySeen(Recorded):
    """The telemetry value a verify, wait or branch decided on: ``system``, ``item``, ``value``,
    ``stale``, ``timestamp`` (the system's, seconds since the epoch; null when it gave none); a
    verify's or wait's ``condition`` (in words) and ``ok`` (whether it held), not written for a
    branch's read."""

    KIND = EventKind.TELEMETRY_SEEN
    system: str | None
    item: str
    value: Any
    stale: bool
    timestamp: float | None
    condition: str | None = optional()
    ok: bool | None = optional()


@dataclass(frozen=True, kw_only=True)
class OperatorInput(Recorded):
    """An operator entered a recorded value: ``name`` (the record's), ``value`` (converted to its
    type); ``checked_against`` (``system.item``) and ``allowed`` (the values that item listed)
    for a record checked against telemetry."""

    KIND = EventKind.OPERATOR_INPUT
    name: str
    value: Any
    checked_against: str | None = optional()
    allowed: tuple[str, ...] | None = optional()


@dataclass(frozen=True, kw_only=True)
class RecordCorrected(Recorded):
    """An operator re-entered an earlier record: ``name``, ``old``, ``value``, ``reason``;
    ``checked_against`` and ``allowed`` as in :class:`OperatorInput`."""

    KIND = EventKind.RECORD_CORRECTED
    name: str
    old: Any
    value: Any
    reason: str
    checked_against: str | None = optional()
    allowed: tuple[str, ...] | None = optional()


@dataclass(frozen=True, kw_only=True)
class SteppedBack(Recorded):
    """An operator went back to an earlier instruction of the step: ``from_`` (stored as ``from``)
    where the run was, ``next`` where it continues, ``reset`` the instructions to be performed
    again, ``reason`` their words."""

    KIND = EventKind.STEPPED_BACK
    from_: str = field(metadata={JSON_NAME: "from"})
    next: str
    reset: tuple[str, ...]
    reason: str


@dataclass(frozen=True, kw_only=True)
class Confirmation(Recorded):
    """An operator confirmed a hazardous command: ``command``, the instruction's sentence filled."""

    KIND = EventKind.CONFIRMATION
    command: str | None = optional()


@dataclass(frozen=True, kw_only=True)
class ApprovalRequested(Recorded):
    """An operator (the sender) asked for a command that needs a second operator's approval to be
    sent (:mod:`pride.approvals`): ``command`` (in words), ``level`` (the policy's)."""

    KIND = EventKind.APPROVAL_REQUESTED
    command: str
    level: str


@dataclass(frozen=True, kw_only=True)
class ApprovalGiven(Recorded):
    """A second operator approved it (the actor): ``sender``, ``command``, ``expires`` (ISO UTC);
    an approval given on the ground and carried up with an onboard unit adds ``given`` (ISO UTC)
    and ``carried``. It is sent at once, its command_sent naming both operators."""

    KIND = EventKind.APPROVAL_GIVEN
    sender: str
    command: str
    expires: str
    given: str | None = optional()
    carried: bool = optional(False)


@dataclass(frozen=True, kw_only=True)
class ApprovalExpired(Recorded):
    """An approval ran out before its command could be sent: ``approver``, ``sender``,
    ``command``, ``expired`` (ISO UTC); nothing was sent and the command waits for a new one."""

    KIND = EventKind.APPROVAL_EXPIRED
    approver: str
    sender: str
    command: str
    expired: str


@dataclass(frozen=True, kw_only=True)
class ActionRefused(Recorded):
    """An operator's act was refused (the actor asked): ``action`` (``approve``, ``perform``,
    ``start`` …), ``rule`` (the value of the :class:`pride.states.RefusalRule` that refused it),
    ``reason`` (the words the operator was shown); ``asked``: what the request carried besides the
    action (the instruction clicked, a value, a binding), when it carried anything. The event's
    instruction is the one the act named. A start refused is recorded under a run id of its own,
    which holds nothing else (the run never started); so is a refused attach (``attach``: an
    onboard run's log is the habitat's chain)."""

    KIND = EventKind.ACTION_REFUSED
    action: str
    rule: str
    reason: str
    asked: Mapping[str, Any] | None = optional()


@dataclass(frozen=True, kw_only=True)
class SupervisorAttached(Recorded):
    """The actor attached a new supervising runner to onboard run ``run``, whose supervisor was
    gone; ``supervisor``: that runner, as the consoles name its host. Recorded under a run id of
    its own, ``<run>-attach-<UTC>-<hex>``, which holds nothing else: the onboard run's own log is
    the habitat's chain, which the ground keeps hash for hash."""

    KIND = EventKind.SUPERVISOR_ATTACHED
    run: str
    supervisor: str


# ---- automation -----------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class AwaitingOperator(Recorded):
    """Automation holds at an instruction until an operator acts: ``hold`` (:class:`pride.states.Hold`'s
    value), ``reason`` in words."""

    KIND = EventKind.AWAITING_OPERATOR
    hold: str
    reason: str


@dataclass(frozen=True, kw_only=True)
class Paused(Recorded):
    """Automation paused: by an operator, or after ``after_step`` (the instruction an operator
    stepped through)."""

    KIND = EventKind.PAUSED
    after_step: str | None = optional()


@dataclass(frozen=True, kw_only=True)
class Continued(Recorded):
    """An operator let automation continue."""

    KIND = EventKind.CONTINUED


@dataclass(frozen=True, kw_only=True)
class BreakpointSet(Recorded):
    """An operator set a breakpoint at the event's instruction."""

    KIND = EventKind.BREAKPOINT_SET


@dataclass(frozen=True, kw_only=True)
class BreakpointCleared(Recorded):
    """An operator removed the breakpoint at the event's instruction."""

    KIND = EventKind.BREAKPOINT_CLEARED


@dataclass(frozen=True, kw_only=True)
class BreakpointHit(Recorded):
    """Automation reached a breakpoint (the event's instruction)."""

    KIND = EventKind.BREAKPOINT_HIT


@dataclass(frozen=True, kw_only=True)
class Retry(Recorded):
    """An operator asked to perform a failed, halted or interrupted instruction again (a new
    attempt, a new key): ``after`` what ended the last one. With ``same_key``, they asked again
    about a command of unknown outcome: ``key`` is re-sent, and the habitat answers its outcome or
    joins it, never runs it twice."""

    KIND = EventKind.RETRY
    after: str
    same_key: bool = optional(False)
    key: str | None = optional()


@dataclass(frozen=True, kw_only=True)
class CallEntered(Recorded):
    """A sub-procedure started: ``procedure`` (its id), ``inputs`` (name → value)."""

    KIND = EventKind.CALL_ENTERED
    procedure: str
    inputs: Mapping[str, Any]


@dataclass(frozen=True, kw_only=True)
class ValueSet(Recorded):
    """A ``<set>`` gave an output of the procedure it is in a value: ``name`` (the output's),
    ``value`` (converted to its type)."""

    KIND = EventKind.VALUE_SET
    name: str
    value: Any


@dataclass(frozen=True, kw_only=True)
class CallReturned(Recorded):
    """A sub-procedure ended (the event's instruction is the call): ``procedure`` (its id),
    ``result`` (the name its caller reads them under, null if the call names none) and ``outputs``
    (name → value)."""

    KIND = EventKind.CALL_RETURNED
    procedure: str
    result: str | None
    outputs: Mapping[str, Any]


#: What an event's ``data`` is: one of these, by its kind.
Payload: TypeAlias = (
    RunStarted
    | RunResumed
    | RunCompleted
    | RunStopped
    | ModeChanged
    | InstructionStarted
    | InstructionCompleted
    | InstructionFailed
    | InstructionSkipped
    | InstructionHalted
    | CommandSent
    | CommandResult
    | OutcomeResolved
    | Halt
    | LinkLost
    | LinkRestored
    | ControlTaken
    | ControlLost
    | RecordCorrected
    | SteppedBack
    | TelemetrySeen
    | OperatorInput
    | Confirmation
    | ApprovalRequested
    | ApprovalGiven
    | ApprovalExpired
    | ActionRefused
    | SupervisorAttached
    | AwaitingOperator
    | Paused
    | Continued
    | BreakpointSet
    | BreakpointCleared
    | BreakpointHit
    | Retry
    | CallEntered
    | ValueSet
    | CallReturned
    | MonitorViolated
    | MonitorCleared
    | WentTo
)

_BY_KIND: dict[EventKind, type[Recorded]] = {cls.KIND: cls for cls in typing.get_args(Payload)}
assert set(_BY_KIND) == set(EventKind), "every kind has its payload"


def _leftovers(left_behind: tuple[Mapping[str, Any], ...]) -> tuple[tuple[str, str, str], ...]:
    return tuple((str(i.get("system", "")), str(i.get("name", "")), str(i.get("why", ""))) for i in left_behind)


def payload_from_json(kind: EventKind, data: object) -> Payload:
    """Read a stored event's ``data`` (parsed JSON) into its kind's payload (:func:`pride.event_json.read_payload`).

    Raises:
        EventDataError: ``data`` is not an object, or a field's value is not of its type.
    """
    return typing.cast(Payload, read_payload(_BY_KIND[kind], data))
