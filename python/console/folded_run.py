"""What the page shows of a run, folded from its audit events alone.

The audit log is the record of what happened, so the view is a pure function of it: the same
fold draws a live run (events as the executive emits them) and a past one (events read back
from the log). Folding never touches the executive, so watching cannot change a run.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

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
        data = event.data or {}
        kind = event.kind
        when = event.time.isoformat()
        number = event.instruction
        entry = self.instructions.setdefault(number, InstructionState()) if number else None
        frame = number.rsplit("/", 1)[0] + "/" if number and "/" in number else ""
        if kind in _ARRIVALS:
            self.arrived = when
        if kind in (EventKind.RUN_STARTED, EventKind.RUN_RESUMED):
            self.procedure = data.get("procedure", self.procedure)
            self.mode = data.get("mode", self.mode)
            self.started_by = self.started_by or event.actor
            self.status = "running"
            if kind is EventKind.RUN_STARTED and "sha256" in data:
                self.version = {key: data.get(key) for key in ("sha256", "release", "rehearsal")}
        elif kind is EventKind.MODE_CHANGED:
            self.mode = data.get("mode", data.get("to", self.mode))
        elif kind is EventKind.RUN_COMPLETED:
            self.status, self.current, self.awaiting = "completed", None, None
        elif kind is EventKind.RUN_STOPPED:
            self.status, self.awaiting = "stopped", None
            self.stopped = {"by": event.actor, "time": when, "reason": str(data.get("reason") or "")}
        elif kind is EventKind.PAUSED:
            self.status, self.paused = "paused", True
        elif kind is EventKind.CONTINUED:
            self.status, self.awaiting, self.paused = "running", None, False
        elif kind is EventKind.RETRY:
            self.status, self.awaiting = "running", None
        elif kind is EventKind.BREAKPOINT_SET and number:
            self.breakpoints.add(number)
        elif kind is EventKind.BREAKPOINT_CLEARED and number:
            self.breakpoints.discard(number)
        elif kind is EventKind.CALL_ENTERED and number:
            self.envs[number + "/"] = dict(data.get("inputs") or {})
        elif kind is EventKind.HALT:
            self.halted = {"by": event.actor, "time": when, "reason": str(data.get("reason") or "")}
        elif kind is EventKind.LINK_LOST:
            self.link = {
                "state": "lost",
                "since": data.get("since"),
                "in_flight": data.get("in_flight", 0),
                "quiet": bool(data.get("quiet")),
            }
        elif kind is EventKind.LINK_RESTORED:
            self.link = {"state": "connected", "since": when}
        if entry is None:
            return
        if kind is EventKind.INSTRUCTION_STARTED:
            entry.status, entry.actor, entry.time, entry.started, entry.reason = "active", event.actor, when, when, None
            self.current, self.awaiting = number, None
            if self.status == "awaiting":
                self.status = "running"
        elif kind in (EventKind.AWAITING_OPERATOR, EventKind.BREAKPOINT_HIT):
            entry.status = "awaiting"
            entry.reason = data.get("reason") or ("breakpoint" if kind is EventKind.BREAKPOINT_HIT else None)
            self.current, self.awaiting, self.status = number, entry.reason or "operator", "awaiting"
        elif kind is EventKind.INSTRUCTION_COMPLETED:
            entry.status, entry.actor, entry.time, entry.reason = "completed", event.actor, when, None
        elif kind is EventKind.INSTRUCTION_FAILED:
            entry.status, entry.actor, entry.time = "failed", event.actor, when
            entry.reason = data.get("reason")
        elif kind is EventKind.INSTRUCTION_SKIPPED:
            entry.status, entry.actor, entry.time = "skipped", event.actor, when
            entry.reason = data.get("reason")
        elif kind is EventKind.INSTRUCTION_HALTED:
            entry.status, entry.actor, entry.time = "halted", event.actor, when
            entry.reason = data.get("reason")
        elif kind is EventKind.CONFIRMATION:
            entry.confirmed_by = event.actor
        elif kind is EventKind.OUTCOME_RESOLVED:
            entry.resolved = {"by": event.actor, "outcome": data.get("outcome"), "reason": data.get("reason", "")}
        elif kind is EventKind.RECORD_CORRECTED:
            entry.value = data.get("value")
            entry.corrected = {
                "by": event.actor,
                "old": data.get("old"),
                "value": data.get("value"),
                "reason": data.get("reason", ""),
            }
            self.envs.setdefault(frame, {})[str(data.get("name"))] = data.get("value")
        elif kind is EventKind.COMMAND_SENT:
            entry.sent, entry.sent_by = dict(data), event.actor
        elif kind is EventKind.COMMAND_RESULT:
            entry.result, entry.outcome = dict(data), data.get("outcome")
            values: dict[str, Any] = data["values"] if isinstance(data.get("values"), dict) else {}
            entry.result_lines = labelled_values(values, self.sysreps.get(str(data.get("system"))))
            if data.get("result"):
                self.envs.setdefault(frame, {})[data["result"]] = {
                    "success": data.get("success"),
                    "message": data.get("message", ""),
                    **values,
                }
            image = _image_path(data)
            if image:
                self.latest_image, self.latest_image_event = image, event
        elif kind is EventKind.OPERATOR_INPUT:
            entry.value = data.get("value")
            self.envs.setdefault(frame, {})[str(data.get("name"))] = data.get("value")
        elif kind is EventKind.TELEMETRY_SEEN:
            entry.telemetry = dict(data)


def _image_path(data: dict[str, Any]) -> str | None:
    """A PNG path in a command result (the camera SysRep's capture answers with one)."""
    values = data.get("values") if isinstance(data.get("values"), dict) else data
    for key in _IMAGE_KEYS:
        value = values.get(key) if isinstance(values, dict) else None
        if isinstance(value, str) and value.lower().endswith(".png"):
            return value
    return None


def fold_events(run_id: str, events: list[Event], sysreps: Mapping[str, SysRep] | None = None) -> FoldedRun:
    """The state of a run after ``events``."""
    state = FoldedRun(run_id, sysreps or {})
    for event in events:
        state.apply(event)
    return state
