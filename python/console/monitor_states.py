"""Telemetry against its limits and monitors as the page shows them, from values and the record.

- A telemetry value against its SysRep limits (:mod:`procedure_language.limits`): its colour and
  the same state in words (``RED HIGH``, ``YELLOW LOW``, as COSMOS names limit states), so no
  state is told by colour alone.
- What the run's record says each monitor saw (:class:`MonitorNews`): its last violation or clear
  and where the run is, folded from the events alone, so a past run shows it as a live one does.
  From it the page (``static/monitors.js``) works out which monitors are active, as
  :class:`pride.monitoring.MonitorBoard` does: a step's while the run is in that step, a
  procedure-scoped one from its step on; what a monitor saw before it last became active (or
  before a resume, which starts the executive's monitors afresh) no longer counts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pride import event_payloads as ep
from pride.events import Event
from procedure_language.limits import GREEN, RED, Limits
from procedure_language.sysrep import Telemetry

__all__ = ["MonitorNews", "limit_state", "main_step"]

#: Events whose instruction is where the run is (a breakpoint's or a refusal's may name any other).
_WHERE_THE_RUN_IS = (
    ep.InstructionStarted,
    ep.AwaitingOperator,
    ep.BreakpointHit,
    ep.CommandSent,
    ep.InstructionCompleted,
    ep.InstructionFailed,
    ep.InstructionSkipped,
    ep.InstructionHalted,
    ep.MonitorViolated,
    ep.MonitorCleared,
)


def limit_state(item: Telemetry | None, value: Any) -> dict[str, str | None] | None:
    """``value`` against ``item``'s limits: ``state`` (green, yellow, red), ``words`` (``YELLOW
    HIGH``) and ``limit`` (what it is out of: ``yellow above 40``; None when green); None for an
    item without limits or without a value."""
    limits = item.limits if item is not None else None
    if limits is None or value is None:
        return None
    state = limits.state(value)
    limit = limits.describe(state) if state != GREEN else None
    return {"state": state, "words": _words(limits, state, value), "limit": limit}


def _words(limits: Limits, state: str, value: Any) -> str:
    if state == GREEN or limits.equals is not None or isinstance(value, bool) or not isinstance(value, (int, float)):
        return state.upper()  # an equals, or a value no band can place (not a number): no side to name
    low = limits.red_low if state == RED else limits.yellow_low
    return f"{state.upper()} {'LOW' if low is not None and value < low else 'HIGH'}"


def main_step(number: str) -> int:
    """The step of the run's own procedure an instruction number is in (``2.1/1.3`` is in step 2)."""
    return int(number.split("/", 1)[0].split(".", 1)[0])


@dataclass
class MonitorNews:
    """What the record says of the run's monitors. ``seen``: each monitor's last violation or clear
    (by its name), with how often it was violated; ``step`` the step of the main procedure the run
    was last recorded in, since event ``step_since``; ``entered`` the steps entered since the run
    started or was last resumed (event ``resumed``)."""

    seen: dict[str, dict[str, Any]] = field(default_factory=dict)
    step: int | None = None
    step_since: int = 0
    entered: set[int] = field(default_factory=set)
    resumed: int = 0

    def apply(self, event: Event) -> None:
        data = event.data
        if isinstance(data, ep.RunResumed):  # the executive's monitors start afresh, as if never entered
            self.resumed, self.step, self.entered = event.seq, None, set()
        number = data.next if isinstance(data, ep.WentTo) else event.instruction
        if number and isinstance(data, (*_WHERE_THE_RUN_IS, ep.WentTo)):
            step = main_step(number)
            if step != self.step:
                self.step, self.step_since = step, event.seq
            self.entered.add(step)
        if isinstance(data, (ep.MonitorViolated, ep.MonitorCleared)):
            before = self.seen.get(data.monitor, {})
            violated = isinstance(data, ep.MonitorViolated)
            self.seen[data.monitor] = {
                "violated": violated,
                "value": data.value,
                "limit": data.limit if isinstance(data, ep.MonitorViolated) else None,
                "action": data.action if isinstance(data, ep.MonitorViolated) else None,
                "time": event.time.isoformat(),
                "instruction": event.instruction,
                "seq": event.seq,
                "violations": before.get("violations", 0) + violated,
            }

    def to_dict(self) -> dict[str, Any]:
        return {
            "seen": self.seen,
            "step": self.step,
            "step_since": self.step_since,
            "entered": sorted(self.entered),
            "resumed": self.resumed,
        }
