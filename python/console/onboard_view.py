"""An onboard run as the ground has heard of it: the page's view of a run that the habitat executes.

The habitat runs the procedure (``caretaker run --onboard``); the ground only hears of it, one
light time late and not at all during an outage. This view is built from what came down and
nothing else: the events the ground has stored (folded as for any run) and the onboard executive's
own snapshot as of one of them. It says how old that news is, and while the habitat is silent it
says since when (``link``: ``silent``), never what the run is probably doing meanwhile.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Mapping
from datetime import UTC, datetime
from typing import Any

from console.folded_run import fold_events
from console.procedure_view import procedure_json
from ground.run_hosts import PublishedView
from pride.events import Event
from procedure_language.model import Procedure
from procedure_language.sysrep import SysRep

__all__ = ["OnboardView"]


def _iso(epoch: float) -> str:
    return datetime.fromtimestamp(epoch, UTC).isoformat()


class OnboardView:
    """The published view of one onboard run; fed by the supervising runner (any thread)."""

    def __init__(
        self,
        run_id: str,
        procedure: Procedure,
        *,
        binding: str,
        started_by: str,
        mode: str,
        sysreps: Mapping[str, SysRep],
        host: str,
        on_change: Callable[[], None] | None = None,
    ) -> None:
        self.run_id = run_id
        self.binding = binding
        self.started_by = started_by
        self.host = host
        self.procedure_view = procedure_json(procedure, sysreps=sysreps)
        self._mode = mode
        self._sysreps = dict(sysreps)
        self._on_change = on_change
        self._lock = threading.Lock()  # guards what follows
        self._folded = fold_events(run_id, [], self._sysreps)
        self._snapshot: Mapping[str, Any] | None = None
        self._habitat_time = ""
        self._heard: float | None = None
        self._silent_since: float | None = None
        self._waiting = ""
        self._last_age: float | None = None  # how old the newest event was when it arrived

    def event(self, event: Event) -> None:
        """An event the ground has just stored."""
        with self._lock:
            self._folded.apply(event)
            self._last_age = max(time.time() - event.time.timestamp(), 0.0)
        self._changed()

    def stored_before(self, events: Iterable[Event]) -> None:
        """The events the ground stored before this view began (an attach: by the run's earlier
        supervisors), folded without an arrival age: they did not arrive now."""
        with self._lock:
            for event in events:
                self._folded.apply(event)
        self._changed()

    def news(
        self,
        *,
        snapshot: Mapping[str, Any] | None,
        habitat_time: str,
        heard: float,
        waiting: str,
        silent_since: float | None,
    ) -> None:
        """What the habitat last answered (``snapshot`` as of an event stored here), or that it is silent."""
        with self._lock:
            if snapshot is not None:
                self._snapshot = snapshot
            self._habitat_time = habitat_time or self._habitat_time
            self._heard = heard
            self._waiting = waiting
            self._silent_since = silent_since
        self._changed()

    def goes_on(self) -> bool:
        """Whether the run started on the habitat and the ground holds no end of it: a supervisor
        that stops now leaves it to run on without one."""
        with self._lock:
            return self._folded.last_seq > 0 and self._folded.status not in ("completed", "stopped")

    def _changed(self) -> None:
        if self._on_change is not None:
            self._on_change()

    def state_json(self) -> dict[str, Any]:
        """The run as the page draws it; ``onboard`` says what the ground heard, and when."""
        with self._lock:
            details = self._folded.to_dict()
            snapshot = dict(self._snapshot) if self._snapshot is not None else {"status": "active", "mode": self._mode}
            silent_since, heard = self._silent_since, self._heard
            onboard = {
                "habitat_time": self._habitat_time or None,
                "heard": _iso(heard) if heard is not None else None,
                "last_seq": details["last_seq"],
                "last_event_age_s": self._last_age,
                "waiting": self._waiting,
                "at": snapshot.get("current") or details.get("current"),
            }
        # The habitat's own link to its robot is in its events; the banner is the ground's link to the habitat.
        link = (
            {"state": "silent", "since": _iso(silent_since), "in_flight": 0}
            if silent_since is not None
            else {"state": "connected"}
        )
        return {
            **details,
            **snapshot,
            "link": link,
            "onboard": onboard,
            "camera": None,
            "binding": self.binding,
            "started_by": self.started_by,
            "live": True,
            "watchers": [],
            "host": self.host,
            "hosted_here": True,
        }

    def published_view(self) -> PublishedView:
        """The run as consoles show it (:mod:`ground.run_hosts` publishes it)."""
        state = self.state_json()
        telemetry: dict[str, Any] = {"readings": [], "checks": {}}  # the habitat's telemetry stays there
        return PublishedView({"state": state, "telemetry": telemetry}, str(state["status"]), str(state["mode"]))
