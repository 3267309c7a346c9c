"""The runs a web server knows: the ones it started or resumed (live) and every run in the audit log.

Starting a run here is what ``caretaker run`` does, minus the terminal: lint the procedure
against the SysReps (a procedure with problems never starts), open the gateway named by the
binding, create the executive journaling into the audit log, and start it as the signed-in user.
Resuming one is ``caretaker run --resume``: the executive rebuilds the run from its log
(:meth:`Executive.resume`). Procedures and bindings are chosen by file name from the configured
directories, so a request can never name an arbitrary path on the server.
"""

from __future__ import annotations

import logging
import secrets
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from pride.audit_log import AuditLog
from pride.diagnostics import ProcedureError
from pride.events import Event, EventKind
from pride.executive import Executive, Mode, OperatorActionError, RunStatus
from pride.gateways import open_gateway
from pride.lint import CheckedProcedure, check_procedure
from pride.robot_control import RobotControl
from pride.sysrep import SysRep, load_sysrep_dir
from pride.systems import SystemGateway
from pride.web.actions import ActionRefused
from pride.web.camera_feed import CameraFeed
from pride.web.live_run import LiveRun
from pride.web.run_state import fold_events

__all__ = ["CameraSettings", "Catalog", "RunBoard"]

log = logging.getLogger(__name__)

#: How long the listing trusts the status it read from the log of a run that is not live here
#: (another console or a terminal may be running it); a completed run never changes.
_STATUS_TTL_S = 10.0


@dataclass(frozen=True)
class CameraSettings:
    """Which camera the live feed captures while the robot moves (None: no live feed), how often."""

    camera: str | None = None
    period: float = 0.5


@dataclass(frozen=True)
class Catalog:
    """Where procedures, bindings and SysReps are read from."""

    procedures: Path
    bindings: Path
    sysreps: Path

    def procedure_files(self) -> list[str]:
        return sorted(p.name for p in self.procedures.glob("*.xml"))

    def binding_files(self) -> list[str]:
        return sorted(p.name for p in self.bindings.glob("*.yaml")) if self.bindings.is_dir() else []

    def procedure_path(self, name: str) -> Path:
        return _choose(self.procedures, name, self.procedure_files(), "procedure")

    def binding_path(self, name: str) -> Path:
        return _choose(self.bindings, name, self.binding_files(), "binding")


def _mode(name: str) -> Mode:
    try:
        return Mode(name)
    except ValueError:
        raise ActionRefused(400, f"mode must be manual or autonomous (got {name!r})") from None


def _choose(directory: Path, name: str, known: list[str], what: str) -> Path:
    if name not in known:
        raise ActionRefused(400, f"unknown {what} {name!r}; known: {', '.join(known) or 'none'} (in {directory})")
    return directory / name


class RunBoard:
    """Live runs by id, and the audit log they all write to."""

    def __init__(
        self, catalog: Catalog, audit_log: AuditLog, camera: CameraSettings = CameraSettings(), *, rosbridge_url: str | None = None
    ) -> None:
        self.catalog = catalog
        self.audit_log = audit_log
        self.control = RobotControl(audit_log.url)  # one controlling run per robot, across consoles
        self.camera = camera
        self.rosbridge_url = rosbridge_url
        self._lock = threading.Lock()  # guards _live, _statuses
        self._live: dict[str, LiveRun] = {}
        self._statuses: dict[str, tuple[str, float]] = {}  # run id -> (status from its log, when read)

    def sysreps(self) -> dict[str, SysRep]:
        return load_sysrep_dir(self.catalog.sysreps)

    def start(self, user: str, procedure_name: str, binding_name: str, mode_name: str) -> LiveRun:
        """Lint, open the gateway, start the executive; ActionRefused says what to fix."""
        mode = _mode(mode_name)
        checked, gateway = self._open(procedure_name, binding_name)
        run_id = f"{checked.procedure.id}-{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}-{secrets.token_hex(2)}"
        executive = Executive(checked, gateway, self.audit_log, run_id=run_id, mode=mode, control=self.control)
        live = self._hold(executive, gateway, checked, binding_name, user)
        try:
            executive.start(user)
        except OperatorActionError as exc:  # e.g. another run controls the robot: it names that run
            self._retire(run_id)
            raise ActionRefused(409, str(exc)) from None
        log.info("%s started run %s of %s (%s, %s)", user, run_id, procedure_name, binding_name, mode.value)
        return live

    def resume(self, user: str, run_id: str, binding_name: str, mode_name: str) -> LiveRun:
        """Continue a stopped or interrupted run from its log on ``binding_name``; ActionRefused says why not."""
        mode = _mode(mode_name)
        if self.live(run_id) is not None:  # (a run that has just ended is released in a moment)
            raise ActionRefused(409, f"run {run_id} is live on this server (or ending): resume it once it shows as stopped")
        events = self.past_events(run_id)
        status = fold_events(run_id, events).status
        if status == "completed":
            raise ActionRefused(409, f"run {run_id} is completed: there is nothing to resume")
        procedure_name = Path(str(events[0].data.get("path", ""))).name
        checked, gateway = self._open(procedure_name, binding_name)
        try:
            executive = Executive.resume(checked, gateway, self.audit_log, events, user, mode=mode, control=self.control)
        except (OperatorActionError, ValueError) as exc:
            gateway.close()
            raise ActionRefused(409, f"run {run_id} cannot be resumed: {exc}") from None
        live = self._hold(executive, gateway, checked, binding_name, events[0].actor, history=events)
        live.catch_up(self.audit_log.events(run_id))  # what the executive recorded before the listener was attached
        log.info("%s resumed run %s of %s (%s, %s)", user, run_id, procedure_name, binding_name, mode.value)
        return live

    def _open(self, procedure_name: str, binding_name: str) -> tuple[CheckedProcedure, SystemGateway]:
        """The checked procedure (with its SysReps) and an open gateway that serves every system it uses."""
        path = self.catalog.procedure_path(procedure_name)
        binding = self.catalog.binding_path(binding_name)
        try:
            checked = check_procedure(path, self.sysreps())
        except ProcedureError as exc:
            raise ActionRefused(422, "the procedure has problems and cannot start:\n" + str(exc)) from None
        procedure = checked.procedure
        try:
            gateway = open_gateway(str(binding), rosbridge_url=self.rosbridge_url)
        except Exception as exc:  # the host's errors (bad binding, no jar, no rosbridge) refuse the start
            log.exception("opening %s", binding)
            raise ActionRefused(502, f"cannot reach the systems of {binding_name}: {type(exc).__name__}: {exc}") from None
        missing = {system for system, _ in procedure.uses} - gateway.system_ids()
        if missing:
            gateway.close()
            raise ActionRefused(422, f"binding {binding_name} serves no {', '.join(sorted(missing))}, which {procedure_name} uses")
        return checked, gateway

    def _hold(
        self, executive: Executive, gateway: SystemGateway, checked: CheckedProcedure,
        binding_name: str, started_by: str, history: list[Event] | None = None,
    ) -> LiveRun:
        """Keep a run as live here, with a camera feed when the server has a camera to watch."""
        feed = None
        if self.camera.camera is not None and CameraFeed.available(gateway):
            feed = CameraFeed(gateway, self.camera.camera, period=self.camera.period)
        live = LiveRun(executive, gateway, checked.procedure, binding=binding_name, started_by=started_by,
                       sysreps=dict(checked.sysreps), camera_feed=feed, history=history)
        with self._lock:
            self._live[executive.run_id] = live
        executive.add_listener(lambda event: self._on_end(executive.run_id, event))
        return live

    def _on_end(self, run_id: str, event: Event) -> None:
        """An executive listener: once a run has ended it becomes a past run (resumable when stopped).

        Called with the executive's lock held, so the retiring happens on a thread of its own.
        """
        if event.kind in (EventKind.RUN_COMPLETED, EventKind.RUN_STOPPED):
            threading.Thread(target=self._retire, args=(run_id,), name=f"retire-{run_id}", daemon=True).start()

    def _retire(self, run_id: str) -> None:
        with self._lock:
            live = self._live.pop(run_id, None)
            self._statuses.pop(run_id, None)  # read its end from the log next time
        if live is not None:  # whoever took it out of the board closes it (this, or close())
            _release(live)

    def live(self, run_id: str) -> LiveRun | None:
        with self._lock:
            return self._live.get(run_id)

    def require_live(self, run_id: str) -> LiveRun:
        live = self.live(run_id)
        if live is None:
            raise ActionRefused(404, f"run {run_id!r} is not running in this server (past runs are read-only)")
        return live

    def past_events(self, run_id: str) -> list[Event]:
        events = self.audit_log.events(run_id)
        if not events:
            raise ActionRefused(404, f"no run {run_id!r} in the audit log")
        return events

    def listing(self, limit: int = 100) -> list[dict[str, Any]]:
        """The newest runs in the audit log with their status: live here (active, or finished since),
        or as their log ends (completed, stopped, or interrupted: no end recorded)."""
        with self._lock:
            live = dict(self._live)
        rows = []
        for run_id, started, procedure in list(reversed(self.audit_log.runs()))[:limit]:
            entry: dict[str, Any] = {"run_id": run_id, "started": started.isoformat(), "procedure": procedure}
            if run_id in live:
                snapshot = live[run_id].executive.snapshot()
                entry.update(status=snapshot.status.value, mode=snapshot.mode.value, started_by=live[run_id].started_by,
                             live=snapshot.status is RunStatus.ACTIVE)
            else:
                entry.update(status=self._logged_status(run_id), live=False)
            rows.append(entry)
        return rows

    def _logged_status(self, run_id: str) -> str:
        with self._lock:
            known = self._statuses.get(run_id)
        if known is not None and (known[0] == "completed" or time.monotonic() - known[1] < _STATUS_TTL_S):
            return known[0]
        folded = fold_events(run_id, self.audit_log.events(run_id)).status
        status = folded if folded in ("completed", "stopped") else "interrupted"
        with self._lock:
            self._statuses[run_id] = (status, time.monotonic())
        return status

    def close(self) -> None:
        """Stop watching: stop active runs (they stay resumable from the log) and close gateways."""
        with self._lock:
            runs = list(self._live.values())
            self._live.clear()
        for live in runs:
            snapshot = live.executive.snapshot()
            if snapshot.status is RunStatus.ACTIVE:
                try:
                    live.executive.stop("web-server", "the web server shut down")
                except Exception:
                    log.exception("stopping run %s", live.run_id)
            _release(live)
        self.control.close()


def _release(live: LiveRun) -> None:
    """Close an ended run's camera feed and gateway, once a command in flight has finished and been recorded."""
    live.executive.wait_for(lambda snapshot: not snapshot.executing, timeout=10)
    if live.camera_feed is not None:
        live.camera_feed.close()
    try:
        live.gateway.close()
    except Exception:
        log.exception("closing the gateway of run %s", live.run_id)
    live.retire()
