"""Monitors: conditions PAX watches on every telemetry update while they are active, whatever runs.

A procedure declares them (``<monitor>`` in a step: :class:`procedure_language.model.Monitor`):
a condition on a telemetry item, or the item's SysRep limits (:mod:`procedure_language.limits`).
A step's monitors are active while the run is in that step (a sub-procedure it calls included),
a ``scope="procedure"`` one from its step to the run's end. A value out for the monitor's
persistence violates it: the run records ``monitor_violated`` and holds (a pause after the
instruction in progress), halts (as an operator's HALT: the command in flight is cancelled at
once), or halts and goes to a contingency step; when the value comes back, ``monitor_cleared``.
The executive is the same on the ground and onboard, so both watch alike.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from procedure_language.limits import GREEN, RED, YELLOW, Persistence
from procedure_language.model import Monitor, Procedure
from procedure_language.sysrep import SysRep

__all__ = ["MonitorBoard", "MonitorChange", "Responder", "respond"]

#: What the run's record calls PAX acting on a monitor (the actor of its halt, hold or go-to).
MONITOR_ACTOR = "PAX"
_WORSE = {GREEN: 0, YELLOW: 1, RED: 2}


@dataclass(frozen=True)
class MonitorChange:
    """A monitor became violated (``violated``) or cleared, at ``value``; ``limit``: what it is
    out of (or was), in words."""

    monitor: Monitor
    violated: bool
    value: Any
    limit: str

    @property
    def reason(self) -> str:
        """The words a halt or a hold for it carries."""
        item = f"{self.monitor.system}.{self.monitor.telemetry}"
        return f"monitor {self.monitor.describe()}: {item} = {self.value} ({self.limit})"


@dataclass
class _Watch:
    monitor: Monitor
    out_samples: int = 0
    out_since: float | None = None
    violated: bool = False
    value: Any = None
    state: str = GREEN


class MonitorBoard:
    """The run's monitors: which are active (:meth:`enter` says where the run is) and what each saw."""

    def __init__(self, procedure: Procedure, sysreps: Mapping[str, SysRep]) -> None:
        self._watches = [_Watch(m) for step in procedure.steps for m in step.monitors]
        self._sysreps = sysreps
        self._step: int | None = None
        self._entered: set[int] = set()
        self._items = {(w.monitor.system, w.monitor.telemetry) for w in self._watches}

    def watches(self, system: str, item: str) -> bool:
        """Whether any monitor of the procedure reads ``system.item`` (cheap: read without the run's lock)."""
        return (system, item) in self._items

    def enter(self, step: int) -> None:
        """The run is in step ``step`` of its main procedure now; monitors no longer active forget what they saw."""
        self._step = step
        self._entered.add(step)
        for watch in self._watches:
            if not self._active(watch.monitor):
                watch.out_samples, watch.out_since, watch.violated = 0, None, False

    def resume(self, entered: Iterable[int], current: int | None) -> None:
        """A resumed run: the steps its record shows it was in (their procedure-scoped monitors are
        watched again: a resume must not leave one silently unwatched) and the step it is in now."""
        self._entered = set(entered) | ({current} if current is not None else set())
        self._step = current

    def _active(self, monitor: Monitor) -> bool:
        if monitor.scope == "procedure":
            return monitor.step in self._entered
        return monitor.step == self._step

    def update(self, system: str, item: str, value: Any, now: float | None = None) -> list[MonitorChange]:
        """A telemetry update: the active monitors on it that became violated or cleared."""
        now = time.monotonic() if now is None else now
        changes: list[MonitorChange] = []
        for watch in self._watches:
            monitor = watch.monitor
            if (monitor.system, monitor.telemetry) != (system, item) or not self._active(monitor):
                continue
            out, watch.state, limit = self._judge(monitor, value)
            watch.value = value
            if not out:
                watch.out_samples, watch.out_since = 0, None
                if watch.violated:
                    watch.violated = False
                    changes.append(MonitorChange(monitor, False, value, limit))
                continue
            watch.out_samples += 1
            watch.out_since = now if watch.out_since is None else watch.out_since
            persistence = monitor.persistence or self._limits_persistence(monitor)
            lasted = watch.out_samples >= persistence.samples and now - watch.out_since >= persistence.seconds
            if lasted and not watch.violated:
                watch.violated = True
                changes.append(MonitorChange(monitor, True, value, limit))
        return changes

    def _limits_persistence(self, monitor: Monitor) -> Persistence:
        """A monitor that states no persistence of its own takes its item's (one sample without)."""
        sysrep = self._sysreps.get(monitor.system)
        item = sysrep.telemetry_item(monitor.telemetry) if sysrep is not None else None
        return item.limits.persistence if item is not None and item.limits is not None else Persistence()

    def _judge(self, monitor: Monitor, value: Any) -> tuple[bool, str, str]:
        """(out, colour, what it is out of in words) for ``value``."""
        sysrep = self._sysreps.get(monitor.system)
        item = sysrep.telemetry_item(monitor.telemetry) if sysrep is not None else None
        if monitor.condition is not None:
            holds = monitor.condition.holds(value, item.type if item is not None else None)
            return not holds, (GREEN if holds else RED), f"must be {monitor.condition.describe()}"
        limits = item.limits if item is not None else None
        if limits is None:  # lint refuses this; a value then is not judged out
            return False, GREEN, "no limits"
        state = limits.state(value)
        return _WORSE[state] >= _WORSE[monitor.limit or RED], state, limits.describe(state if state != GREEN else RED)

    def states(self) -> list[dict[str, Any]]:
        """The active monitors as the console shows them: what each watches, its last value and colour."""
        return [
            {
                "monitor": w.monitor.name,
                "text": w.monitor.describe(),
                "system": w.monitor.system,
                "telemetry": w.monitor.telemetry,
                "value": w.value,
                "state": w.state,
                "violated": w.violated,
                "on_violation": w.monitor.on_violation + (f":{w.monitor.goto}" if w.monitor.goto else ""),
            }
            for w in self._watches
            if self._active(w.monitor)
        ]


class Responder(Protocol):
    """What acts on a violation: the run's executive (:class:`pride.executive.Executive`)."""

    def divert(self, step: str, reason: str) -> bool: ...

    def halt(self, user: str, reason: str = "") -> None: ...


def respond(executive: Responder, change: MonitorChange) -> None:
    """Halt for a violated monitor, and go to its contingency step if it says so
    (:meth:`pride.executive.Executive.divert`); a hold is recorded with the violation itself."""
    monitor = change.monitor
    if monitor.on_violation == "goto" and monitor.goto and not executive.divert(monitor.goto, change.reason):
        return  # nothing was being performed: the run went there at once
    executive.halt(MONITOR_ACTOR, change.reason)
