"""What the page shows of a run, folded from its audit events alone.

The audit log is the record of what happened, so the view is a pure function of it: the same
fold draws a live run (events as the executive emits them) and a past one (events read back
from the log). Folding never touches the executive, so watching cannot change a run.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, assert_never

from console.monitor_states import MonitorNews, limit_state
from pride import event_payloads as ep
from pride.events import Event, EventKind
from pride.phrasing import labelled_values
from procedure_language.sysrep import SysRep

__all__ = ["InstructionState", "FoldedRun", "fold_events"]

_IMAGE_KEYS = ("image_path", "image", "path")
#: Events after which the run is somewhere new or holds for a new reason: a hold is "since" then.
_ARRIVALS = {
    EventKind.RUN_STARTED,
    EventKind.RUN_RESUMED,
    EventKind.INSTRUCTION_COMPLETED,
    EventKind.INSTRUCTION_FAILED,
    EventKind.INSTRUCTION_SKIPPED,
    EventKind.AWAITING_OPERATOR,
    EventKind.BREAKPOINT_HIT,
    EventKind.PAUSED,
    EventKind.CONTINUED,
    EventKind.MODE_CHANGED,
    EventKind.CALL_ENTERED,
    EventKind.CONFIRMATION,
    EventKind.RUN_STOPPED,
    EventKind.RUN_COMPLETED,
}


@dataclass
class InstructionState:
    """One instruction as far as the run got with it."""

    status: str = "pending"  # pending | active | awaiting | completed | failed | skipped | halted
    actor: str | None = None
    outcome: str | None = None  # its command's last outcome: succeeded | failed | unknown | halted
    sent_by: str | None = None  # who sent its command (PAX, or the operator who performed it)
    confirmed_by: str | None = None  # who confirmed its hazardous command
    resolved: dict[str, Any] | None = None  # an unknown outcome as an operator recorded it: by, outcome, reason
    corrected: dict[str, Any] | None = None  # its record re-entered: by, old, value, reason
    time: str | None = None
    started: str | None = None  # when it was last begun (a verify's countdown runs from here)
    reason: str | None = None
    sent: dict[str, Any] | None = None
    result: dict[str, Any] | None = None
    result_lines: list[tuple[str, str]] | None = None  # the result's values as (label, text)
    value: Any = None
    telemetry: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if v is not None}


@dataclass
class FoldedRun:
    """The run as of its last event. ``sysreps`` label result values (they may be missing: then keys show)."""

    run_id: str
    sysreps: Mapping[str, SysRep] = field(default_factory=dict, repr=False)
    procedure: str | None = None
    mode: str | None = None
    status: str = "not started"  # running | paused | awaiting | completed | stopped
    started_by: str | None = None
    current: str | None = None
    awaiting: str | None = None
    breakpoints: set[str] = field(default_factory=set)
    paused: bool = False
    instructions: dict[str, InstructionState] = field(default_factory=dict)
    latest_image: str | None = None
    latest_image_event: Event | None = None
    last_seq: int = 0
    arrived: str | None = None  # since when the run is where it is, as it is
    stopped: dict[str, str] | None = None  # who stopped the run, when and why
    halted: dict[str, str] | None = None  # who halted the run last, when and why
    link: dict[str, Any] | None = None  # the robot link as last recorded: state lost|connected, since, in_flight
    version: dict[str, Any] | None = None  # the procedure version it runs: sha256, release, rehearsal
    #: the values ``${...}`` take, per procedure frame: "" for the main one, "2.1/" in the one 2.1 called
    envs: dict[str, dict[str, Any]] = field(default_factory=dict)
    monitors: MonitorNews = field(default_factory=MonitorNews)  # what the monitors saw, where the run is

    def to_dict(self) -> dict[str, Any]:
        return {
            "run_id": self.run_id,
            "procedure": self.procedure,
            "mode": self.mode,
            "status": self.status,
            "started_by": self.started_by,
            "current": self.current,
            "awaiting": self.awaiting,
            "breakpoints": sorted(self.breakpoints),
            "paused": self.paused,
            "instructions": {n: s.to_dict() for n, s in self.instructions.items()},
            "camera": self.camera_json(),
            "last_seq": self.last_seq,
            "arrived": self.arrived,
            "stopped": self.stopped,
            "envs": self.envs,
            "halted": self.halted,
            "link": self.link,
            "version": self.version,
            "monitors": self.monitors.to_dict(),
        }

    def camera_json(self) -> dict[str, Any] | None:
        """The newest image a command result named, as the page's camera view shows it."""
        event = self.latest_image_event
        if event is None:
            return None
        return {
            "version": f"seq{event.seq}",
            "caption": f"{event.instruction} · {event.time:%H:%M:%S} UTC · {self.latest_image}",
        }

    def apply(self, event: Event) -> None:
        """Fold one more event in (events arrive in sequence order)."""
        self.last_seq = max(self.last_seq, event.seq)
        when = event.time.isoformat()
        number = event.instruction
        # an event of no instruction (an operator's command outside them) changes no instruction's state
        entry = self.instructions.setdefault(number, InstructionState()) if number else InstructionState()
        frame = number.rsplit("/", 1)[0] + "/" if number and "/" in number else ""
        if event.kind in _ARRIVALS:
            self.arrived = when
        self.monitors.apply(event)
        match event.data:
            case ep.RunStarted() | ep.RunResumed() as d:
                self.procedure = d.procedure if isinstance(d, ep.RunStarted) else self.procedure
                self.mode = d.mode
                self.started_by = self.started_by or event.actor
                self.status = "running"
                if isinstance(d, ep.RunStarted) and d.sha256 is not None:
                    self.version = {"sha256": d.sha256, "release": d.release, "rehearsal": d.rehearsal}
            case ep.ModeChanged() as d:
                self.mode = d.new_mode or self.mode
            case ep.RunCompleted():
                self.status, self.current, self.awaiting = "completed", None, None
            case ep.RunStopped() as d:
                self.status, self.awaiting = "stopped", None
                self.stopped = {"by": event.actor, "time": when, "reason": d.reason}
            case ep.Paused():
                self.status, self.paused = "paused", True
            case ep.Continued():
                self.status, self.awaiting, self.paused = "running", None, False
            case ep.Retry():
                self.status, self.awaiting = "running", None
            case ep.BreakpointSet() if number:
                self.breakpoints.add(number)
            case ep.BreakpointCleared() if number:
                self.breakpoints.discard(number)
            case ep.CallEntered() as d if number:
                self.envs[number + "/"] = dict(d.inputs)
            case ep.ValueSet() as d:
                self.envs.setdefault(frame, {})[d.name] = d.value
            case ep.WentTo() as d:
                self.current, self.awaiting = d.next, None
            case ep.CallReturned() as d if d.result:
                self.envs.setdefault(frame, {})[d.result] = dict(d.outputs)
            case ep.Halt() as d:
                self.halted = {"by": event.actor, "time": when, "reason": d.reason}
            case ep.LinkLost() as d:
                self.link = {"state": "lost", "since": d.since, "in_flight": d.in_flight, "quiet": d.quiet}
            case ep.LinkRestored():
                self.link = {"state": "connected", "since": when}
            case ep.InstructionStarted() if number:
                entry.status, entry.actor, entry.time, entry.started, entry.reason = (
                    "active",
                    event.actor,
                    when,
                    when,
                    None,
                )
                self.current, self.awaiting = number, None
                if self.status == "awaiting":
                    self.status = "running"
            case ep.AwaitingOperator() | ep.BreakpointHit() as d if number:
                entry.status = "awaiting"
                entry.reason = d.reason if isinstance(d, ep.AwaitingOperator) and d.reason else None
                entry.reason = entry.reason or ("breakpoint" if isinstance(d, ep.BreakpointHit) else None)
                self.current, self.awaiting, self.status = number, entry.reason or "operator", "awaiting"
            case ep.InstructionCompleted():
                entry.status, entry.actor, entry.time, entry.reason = "completed", event.actor, when, None
            case ep.InstructionFailed() | ep.InstructionSkipped() | ep.InstructionHalted() as d:
                status = {
                    ep.InstructionFailed: "failed",
                    ep.InstructionSkipped: "skipped",
                    ep.InstructionHalted: "halted",
                }
                entry.status, entry.actor, entry.time = status[type(d)], event.actor, when
                entry.reason = d.reason
            case ep.Confirmation():
                entry.confirmed_by = event.actor
            case ep.OutcomeResolved() as d:
                entry.resolved = {"by": event.actor, "outcome": d.outcome, "reason": d.reason}
            case ep.RecordCorrected() as d:
                entry.value = d.value
                entry.corrected = {"by": event.actor, "old": d.old, "value": d.value, "reason": d.reason}
                self.envs.setdefault(frame, {})[d.name] = d.value
            case ep.CommandSent() as d:
                entry.sent, entry.sent_by = d.to_json(), event.actor
            case ep.CommandResult() as d if number:  # an operator's command outside the instructions: its log only
                entry.result, entry.outcome = d.to_json(), d.outcome
                entry.result_lines = labelled_values(d.values, self.sysreps.get(d.system))
                if d.result:
                    self.envs.setdefault(frame, {})[d.result] = {"success": d.success, "message": d.message, **d.values}
                image = _image_path(d)
                if image:
                    self.latest_image, self.latest_image_event = image, event
            case ep.OperatorInput() as d:
                entry.value = d.value
                self.envs.setdefault(frame, {})[d.name] = d.value
            case ep.TelemetrySeen() as d:
                sysrep = self.sysreps.get(d.system or "")
                item = sysrep.telemetry_item(d.item) if sysrep is not None else None
                entry.telemetry = {**d.to_json(), "limit": limit_state(item, d.value)}
            case (
                ep.BreakpointSet()
                | ep.BreakpointCleared()
                | ep.CallEntered()
                | ep.CallReturned()
                | ep.MonitorViolated()
                | ep.MonitorCleared()
                | ep.InstructionStarted()
                | ep.AwaitingOperator()
                | ep.BreakpointHit()
                | ep.CommandResult()
                | ep.SteppedBack()
                | ep.ControlTaken()
                | ep.ControlLost()
                | ep.ApprovalRequested()
                | ep.ApprovalGiven()
                | ep.ApprovalExpired()
                | ep.ActionRefused()
                | ep.SupervisorAttached()
            ):
                pass  # without an instruction, in self.monitors, or shown through the run's snapshot and its log
            case _:
                assert_never(event.data)


def _image_path(data: ep.CommandResult) -> str | None:
    """A PNG path in a command result (the camera SysRep's capture answers with one)."""
    for key in _IMAGE_KEYS:
        value = data.values.get(key)
        if isinstance(value, str) and value.lower().endswith(".png"):
            return value
    return None


def fold_events(run_id: str, events: list[Event], sysreps: Mapping[str, SysRep] | None = None) -> FoldedRun:
    """The state of a run after ``events``."""
    state = FoldedRun(run_id, sysreps or {})
    for event in events:
        state.apply(event)
    return state
