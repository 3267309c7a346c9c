"""The runs a web server knows: the ones it started (live) and every run in the audit log (past).

Starting a run here is what ``caretaker run`` does, minus the terminal: lint the procedure
against the SysReps (a procedure with problems never starts), open the gateway named by the
binding, create the executive journaling into the audit log, and start it as the signed-in user.
Procedures and bindings are chosen by file name from the configured directories, so a request
can never name an arbitrary path on the server.
"""

from __future__ import annotations

import logging
import secrets
import threading
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from pride.audit_log import AuditLog
from pride.diagnostics import ProcedureError
from pride.events import Event
from pride.executive import Executive, Mode, RunStatus
from pride.gateways import open_gateway
from pride.lint import check_procedure
from pride.sysrep import SysRep, load_sysrep_dir
from pride.web.actions import ActionRefused
from pride.web.camera_feed import CameraFeed
from pride.web.live_run import LiveRun

__all__ = ["CameraSettings", "Catalog", "RunBoard"]

log = logging.getLogger(__name__)


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
        self.camera = camera
        self.rosbridge_url = rosbridge_url
        self._lock = threading.Lock()  # guards _live
        self._live: dict[str, LiveRun] = {}

    def sysreps(self) -> dict[str, SysRep]:
        return load_sysrep_dir(self.catalog.sysreps)

    def start(self, user: str, procedure_name: str, binding_name: str, mode_name: str) -> LiveRun:
        """Lint, open the gateway, start the executive; ActionRefused says what to fix."""
        try:
            mode = Mode(mode_name)
        except ValueError:
            raise ActionRefused(400, f"mode must be manual or autonomous (got {mode_name!r})") from None
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
        run_id = f"{procedure.id}-{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}-{secrets.token_hex(2)}"
        executive = Executive(checked, gateway, self.audit_log, run_id=run_id, mode=mode)
        feed = None
        if self.camera.camera is not None and CameraFeed.available(gateway):
            feed = CameraFeed(gateway, self.camera.camera, period=self.camera.period)
        live = LiveRun(executive, gateway, procedure, binding=binding_name, started_by=user, camera_feed=feed)
        with self._lock:
            self._live[run_id] = live
        executive.start(user)
        log.info("%s started run %s of %s (%s, %s)", user, run_id, procedure_name, binding_name, mode.value)
        return live

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

    def listing(self) -> list[dict[str, Any]]:
        """Every run in the audit log, newest first, marking the ones live here."""
        with self._lock:
            live = dict(self._live)
        rows = []
        for run_id, started, procedure in reversed(self.audit_log.runs()):
            entry: dict[str, Any] = {"run_id": run_id, "started": started.isoformat(), "procedure": procedure, "live": run_id in live}
            if run_id in live:
                snapshot = live[run_id].executive.snapshot()
                entry.update(status=snapshot.status.value, mode=snapshot.mode.value, started_by=live[run_id].started_by)
            rows.append(entry)
        return rows

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
            # a command in flight finishes and is recorded before its gateway closes
            live.executive.wait_for(lambda snapshot: not snapshot.executing, timeout=10)
            if live.camera_feed is not None:
                live.camera_feed.close()
            try:
                live.gateway.close()
            except Exception:
                log.exception("closing the gateway of run %s", live.run_id)
