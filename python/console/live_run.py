"""A run in progress as the web view holds it: its executive, its gateway, and who watches it.

The executive does the work; this class only observes it. Its listener (called on the
executive's thread with the executive's lock held) appends the event and wakes the watchers'
send loops on the asyncio side (:mod:`console.watchers`) and the publisher that shows the run
to other consoles (:meth:`published_view`, :mod:`ground.run_hosts`); they then read
:meth:`Executive.snapshot`, which takes the lock, so what they draw is a consistent state and
never a half-applied transition.

Operator actions are not here: :mod:`console.actions` sends them to the executive.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from console.accounts import Account
from console.camera_feed import CameraFeed
from console.folded_run import fold_events
from console.monitor_states import limit_state
from console.procedure_view import monitor_checks, procedure_json, telemetry_checks
from console.watchers import Watcher, Watchers
from ground.run_hosts import PublishedView
from pride.events import Event
from pride.executive import Executive
from pride.systems import SystemGateway
from procedure_language.model import Procedure
from procedure_language.sysrep import SysRep, Telemetry, check_value

__all__ = ["LiveRun"]


class LiveRun:
    """One run started (or resumed) from the web view; lives until the server stops.

    ``history`` is what the audit log held of a resumed run before it was resumed here.
    """

    def __init__(
        self,
        executive: Executive,
        gateway: SystemGateway,
        procedure: Procedure,
        *,
        binding: str,
        started_by: str,
        sysreps: Mapping[str, SysRep],
        camera_feed: CameraFeed | None = None,
        history: list[Event] | None = None,
        host: str = "",
        on_change: Callable[[], None] | None = None,
    ) -> None:
        """``host`` names this process for the page; ``on_change`` is called (any thread, quickly) at each event."""
        self.executive = executive
        self.gateway = gateway
        self.procedure = procedure
        self.binding = binding
        self.started_by = started_by
        self.camera_feed = camera_feed
        self.sysreps = dict(sysreps)
        self.procedure_view = procedure_json(procedure, sysreps=sysreps)
        self._checks = telemetry_checks(procedure) | monitor_checks(procedure)
        self._references = sorted({(system, item) for system, item, _ in self._checks.values()})
        self.host = host
        self._on_change = on_change
        self._lock = threading.Lock()  # guards _events, _state
        self._events: list[Event] = list(history or [])
        self._state = fold_events(executive.run_id, self._events, self.sysreps)
        self._watchers = Watchers()
        self.retired = False  # ended and released: watchers should look at it as a past run
        executive.add_listener(self._event_callback)
        if camera_feed is not None:
            executive.add_listener(camera_feed.event_callback)
        gateway.add_listener(self._telemetry_callback)

    @property
    def run_id(self) -> str:
        return self.executive.run_id

    # ---- observation callbacks (other threads) ----------------------------------------------
    def _event_callback(self, event: Event) -> None:
        with self._lock:
            if self._events and event.seq <= self._events[-1].seq:
                return  # already in the history read back from the log
            self._events.append(event)
            self._state.apply(event)
        self._wake()
        if self._on_change is not None:
            self._on_change()

    def retire(self) -> None:
        """The run ended and its gateway is closed: wake the watchers, who then let go of it."""
        self.retired = True
        self._wake()

    def catch_up(self, logged: list[Event]) -> None:
        """Fold in what the log holds that the listener missed (events of a resume before it was attached)."""
        with self._lock:
            seen = {e.seq for e in self._events}
            missed = [e for e in logged if e.seq not in seen]
            if not missed:
                return
            self._events = sorted([*self._events, *missed], key=lambda e: e.seq)
            self._state = fold_events(self.run_id, self._events, self.sysreps)
        self._wake()

    def _telemetry_callback(self, sysrep_id: str, item_id: str, value: Any) -> None:
        if (sysrep_id, item_id) in self._references:
            self._wake()

    def _wake(self) -> None:
        self._watchers.wake()

    # ---- watchers -----------------------------------------------------------------------------
    def watch(self, account: Account) -> Watcher:
        return self._watchers.add(account)

    def unwatch(self, watcher: Watcher) -> None:
        self._watchers.remove(watcher)
        self._wake()  # the others' lists of who watches change

    def watchers(self) -> list[dict[str, str]]:
        """Who has the run open in this console now (each person once), by user id."""
        return self._watchers.people()

    def refresh(self) -> None:
        """Nothing to fetch: the executive runs here (a :class:`~console.remote_run.RemoteRun` reads the database)."""

    # ---- views --------------------------------------------------------------------------------
    def events_since(self, seq: int) -> list[Event]:
        with self._lock:
            return [e for e in self._events if e.seq > seq]

    def camera(self) -> tuple[Path, dict[str, Any]] | None:
        """The newest camera image, from the procedure's captures or the live feed, and its caption."""
        with self._lock:
            image, from_result = self._state.latest_image, self._state.camera_json()
            event = self._state.latest_image_event
        live = self.camera_feed.latest() if self.camera_feed is not None else None
        if live is not None and (event is None or live.time > event.time.timestamp()):
            caption = (
                "live view while the robot moves · "
                f"{time.strftime('%H:%M:%S', time.gmtime(live.time))} UTC · {live.path}"
            )
            return live.path, {"version": f"live{live.seq}", "caption": caption}
        if image is None or from_result is None:
            return None
        return Path(image), from_result

    def camera_image(self) -> Path | None:
        camera = self.camera()
        return camera[0] if camera else None

    def published_view(self) -> PublishedView:
        """The run as other consoles show it (:mod:`ground.run_hosts` publishes it)."""
        state = self.state_json()
        camera = self.camera()
        return PublishedView(
            {"state": state, "telemetry": self.telemetry_json()},
            str(state["status"]),
            str(state["mode"]),
            (camera[1], camera[0]) if camera else None,
        )

    def state_json(self) -> dict[str, Any]:
        """The run as the page draws it: the executive's snapshot plus who did what, when."""
        snapshot = self.executive.snapshot()
        with self._lock:
            details = self._state.to_dict()
        camera = self.camera()
        return {
            **details,
            **snapshot.to_json(),
            "camera": camera[1] if camera else None,
            "binding": self.binding,
            "started_by": self.started_by,
            "live": True,
            "watchers": self.watchers(),
            "host": self.host,
            "hosted_here": True,
        }

    def telemetry_json(self) -> dict[str, Any]:
        """The value, age and staleness of every telemetry item the procedure reads or monitors,
        whether it is within its SysRep min, max or enum (``out``: why not), its state against its
        SysRep limits (``limit``), and whether each instruction's or monitor's test of it holds now."""
        now = time.time()
        readings = []
        values: dict[tuple[str, str], Any] = {}
        for system, item in self._references:
            try:
                reading = self.gateway.telemetry(system, item)
            except Exception as exc:  # shown as unavailable, never as a value
                readings.append(
                    {"system": system, "item": item, "error": f"{type(exc).__name__}: {exc}", "stale": True}
                )
                continue
            timestamp = reading.timestamp
            value, stale = reading.value, reading.stale
            if not stale and value is not None:
                values[(system, item)] = value
            readings.append(
                {
                    "system": system,
                    "item": item,
                    "value": value,
                    "timestamp": timestamp,
                    "age": (now - timestamp) if timestamp else None,
                    "stale": stale,
                    "out": _out_of_limits(self._item(system, item), value),
                    "limit": limit_state(self._item(system, item), value),
                }
            )
        checks = {}
        for key, (system, item, condition) in self._checks.items():
            definition = self._item(system, item)
            if condition is not None and (system, item) in values:
                checks[key] = condition.holds(values[(system, item)], definition.type if definition else None)
        return {"readings": readings, "checks": checks}

    def _item(self, system: str, item: str) -> Telemetry | None:
        sysrep = self.sysreps.get(system)
        return sysrep.telemetry_item(item) if sysrep is not None else None


def _out_of_limits(item: Telemetry | None, value: Any) -> str | None:
    """Why a value is outside its SysRep limits (min, max, enum, type), or None when it is within them."""
    if item is None or value is None:
        return None
    try:
        check_value(item.label, item.type, value, item.min, item.max, item.enum)
    except ValueError as exc:
        return str(exc).split(": ", 1)[-1]
    return None
