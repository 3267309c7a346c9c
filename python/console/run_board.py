"""The runs a console knows: those it hosts (started or resumed here), those other consoles or
runners host (followed through the database), and every run in the audit log.

Starting a run here is what ``caretaker run`` does, minus the terminal: lint the procedure
against the SysReps (a procedure with problems never starts), open the gateway named by the
binding, create the executive journaling into the audit log, and start it as the signed-in user.
Resuming one is ``caretaker run --resume``: the executive rebuilds the run from its log
(:meth:`Executive.resume`). Procedures and bindings are chosen by file name from the configured
directories, so a request can never name an arbitrary path on the server.

Consoles share runs only through the ground database (:mod:`ground`): a run started here is
claimed in ``run_hosts`` and its view published there; a run hosted elsewhere is shown as a
:class:`~console.remote_run.RemoteRun`, and an operator action on it is forwarded to its host
(:mod:`ground.action_requests`), which performs it as that operator, role checked there too.
The change feed tells this board what changed (new events, hosts, accounts, requests).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Mapping
from datetime import datetime
from functools import partial
from pathlib import Path
from typing import Any

from sqlalchemy.exc import SQLAlchemyError

from console.accounts import Account, AccountStore
from console.actions import ActionRefused, ActionRequest, mode_named, perform_action, perform_forwarded
from console.camera_feed import CameraFeed
from console.catalog import CameraSettings, Catalog, rosbridge_for
from console.folded_run import fold_events
from console.live_run import LiveRun
from console.onboard_launch import LaunchRefused, SecondOperator, hand_onboard, launch_onboard
from console.release_desk import ReleaseDesk
from console.remote_run import RemoteRun
from console.start_refusals import recorded_start_refusals
from console.watchers import Watchers
from ground.action_requests import ActionRequests, Answer, ForwardedAction
from ground.change_feed import ChangeNotice, open_change_feed
from ground.run_hosts import DEFAULT_LEASE_S, HostedElsewhere, HostRecord, RunHosting
from pride.accepted_proposal import AcceptedProposal
from pride.approvals import approval_points, missing_approvals_text
from pride.events import Event, EventKind, run_start
from pride.executive import Executive, Hold, Mode, OperatorActionError, RunStatus
from pride.gateways import open_gateway
from pride.run_control import RobotControlled
from pride.run_setup import RunSetup, load_sysreps
from pride.states import RefusalRule
from pride.systems import SystemGateway
from procedure_language.binding import BindingError, read_binding
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import CheckedProcedure, check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog
from records.releases import ReleaseRefused, ReleaseStore, resume_refusal, version_for_run
from records.robot_control import RobotControl

__all__ = ["RunBoard", "RunView"]

#: A run as a console shows it: hosted here, or elsewhere and followed through the database.
RunView = LiveRun | RemoteRun

log = logging.getLogger(__name__)

_NO_CAMERA = CameraSettings()  # no binding has a live feed

#: How long the listing trusts the status it read from the log of a run that is not live here
#: (another console or a terminal may be running it); a completed run never changes.
_STATUS_TTL_S = 10.0
#: Events that change a run's line in the runs list.
_LISTED = {
    EventKind.RUN_STARTED.value,
    EventKind.RUN_RESUMED.value,
    EventKind.RUN_COMPLETED.value,
    EventKind.RUN_STOPPED.value,
    # a request for a second operator's approval shows in every console's list, not only where the run is open
    EventKind.APPROVAL_REQUESTED.value,
    EventKind.APPROVAL_GIVEN.value,
    EventKind.APPROVAL_EXPIRED.value,
}


class RunBoard:
    """Live runs by id, hosted here or elsewhere, and the audit log they all write to.

    ``console`` names this process to the others ("console HOST:PORT"); ``lease``: how long its
    claim on a run lasts unrenewed; ``rosbridge_urls``: a rosbridge URL per binding file name
    replacing the binding's own ("" for every binding).
    """

    def __init__(
        self,
        catalog: Catalog,
        audit_log: AuditLog,
        camera: CameraSettings = _NO_CAMERA,
        *,
        accounts: AccountStore,
        console: str,
        lease: float = DEFAULT_LEASE_S,
        rosbridge_urls: Mapping[str, str] | None = None,
        via_supervisor: bool = False,
    ) -> None:
        self.catalog = catalog
        self.via_supervisor = via_supervisor  # onboard starts handed to the binding's ``caretaker supervise``
        self.audit_log = audit_log
        self.control = RobotControl(audit_log.url)  # one controlling run per robot, across consoles
        self.camera = camera
        self.accounts = accounts
        self.rosbridge_urls = dict(rosbridge_urls or {})
        self.releases = ReleaseStore(audit_log.engine)
        self.release_desk = ReleaseDesk(catalog, self.releases, self._check)  # the Author page's versions
        self._lock = threading.Lock()  # guards _live, _remote, _statuses, _starts
        self._live: dict[str, LiveRun] = {}
        self._remote: dict[str, RemoteRun] = {}
        self._statuses: dict[str, tuple[str, float]] = {}  # run id -> (status from its log, when read)
        self._starts: list[tuple[str, datetime, dict[str, Any]]] | None = None  # the log's runs, until a new one starts
        self.list_watchers = Watchers()  # browsers showing the runs list
        self.hosting = RunHosting(audit_log.engine, host=console, lease=lease)
        self.hosting.on_lost(self._lost)
        self.forwarding = ActionRequests(
            audit_log.engine, host_id=self.hosting.host_id, console=console, perform=self._perform_forwarded
        )
        self.feed = open_change_feed(audit_log.engine)
        self.feed.subscribe(self._notice)
        self.feed.subscribe(self.forwarding.notice)

    def rosbridge_url_for(self, binding: str) -> str | None:
        """The rosbridge URL given for a binding file (or for every binding); None: the binding's own."""
        return rosbridge_for(self.rosbridge_urls, binding)

    def sysreps(self) -> dict[str, SysRep]:
        return load_sysreps(self.catalog.sysreps)

    def start(
        self,
        user: str,
        procedure_name: str,
        binding_name: str,
        mode_name: str,
        *,
        take_over: str | None = None,
        rehearsal: bool = False,
        proposal: AcceptedProposal | None = None,
    ) -> LiveRun:
        """Lint, check the version may run, open the gateway, start the executive; ActionRefused
        says what to fix.

        A draft or a file changed since its release runs only as a ``rehearsal``, and a rehearsal
        only on a simulator (:mod:`records.releases`). A robot controlled by another run refuses the
        start (409, naming the controller) unless ``take_over`` gives the reason to take it over:
        the other run then holds. A start refused by a rule is recorded (:mod:`console.start_refusals`).
        ``proposal``: the agent's proposal ``user`` accepted, named in the run's record.
        """
        asked = {"binding": binding_name, "mode": mode_name, "rehearsal": rehearsal, "take_over": take_over}
        with recorded_start_refusals(self.audit_log, user, procedure_name, asked):
            mode = mode_named(mode_name)
            return self._start(user, procedure_name, binding_name, mode, take_over, rehearsal, proposal)

    def _start(
        self,
        user: str,
        procedure_name: str,
        binding_name: str,
        mode: Mode,
        take_over: str | None,
        rehearsal: bool,
        proposal: AcceptedProposal | None,
    ) -> LiveRun:
        setup = self._setup(procedure_name, binding_name, rehearsal=rehearsal)
        if take_over is None:
            self._refuse_if_controlled(procedure_name, binding_name)
        gateway = self._gateway(setup, binding_name)
        run_id = setup.run_id
        try:
            executive = setup.executive(gateway, self.audit_log, mode=mode, control=self.control)
        except BaseException as exc:
            gateway.close()
            if isinstance(exc, OperatorActionError):  # e.g. the robot is controlled by another run
                raise _not_started(procedure_name, exc) from None
            raise
        live = self._hold(executive, gateway, setup.checked, binding_name, user)
        try:
            executive.start(user, take_over=take_over, proposal=proposal)
        except OperatorActionError as exc:
            self._drop(live)
            raise _not_started(procedure_name, exc) from None
        log.info("%s started run %s of %s (%s, %s)", user, run_id, procedure_name, binding_name, mode.value)
        return live

    def _refuse_if_controlled(self, procedure_name: str, binding_name: str) -> None:
        """Refuse a start on a robot another run controls before reaching the robot at all.

        Opening a gateway costs seconds of JVM and rosbridge work on a loaded host, and the
        refusal must not wait on it. The executive's atomic take of control stays the real check
        (another run may take the robot between this look and the start).
        """
        try:
            robot = read_binding(self.catalog.binding_path(binding_name)).robot
        except BindingError as exc:
            raise ActionRefused(422, f"binding {binding_name} cannot be read: {exc}") from None
        holder = self.control.holder(robot)
        if holder is not None:
            raise _not_started(procedure_name, RobotControlled(holder))

    def _setup(
        self, procedure_name: str, binding_name: str, *, rehearsal: bool = False, events: list[Event] | None = None
    ) -> RunSetup:
        """The run's set-up (:class:`pride.run_setup.RunSetup`): a new run's, its version decided by
        the release history, or a recorded run's going on (``events``) if it may. ActionRefused 422
        lists the procedure's problems; 409 says why this version may not run."""
        side = self.catalog.robot_side(binding_name)
        shown = self.catalog.shown(procedure_name)
        path = self.catalog.procedure_path(procedure_name)
        try:
            if events is None:
                return RunSetup.prepare(
                    path,
                    side,
                    self.sysreps(),
                    version=lambda checked, side: version_for_run(
                        self.releases, checked, shown, side, rehearsal=rehearsal
                    ),
                )
            setup = RunSetup.resuming(path, side, self.sysreps(), events)
        except ProcedureError as exc:
            problems = "the procedure has problems and cannot start:\n" + str(exc)
            raise ActionRefused(422, problems, rule=RefusalRule.VALID_PROCEDURE) from None
        except ReleaseRefused as exc:
            raise ActionRefused(409, str(exc), rule=RefusalRule.RELEASED_VERSION) from None
        refusal = resume_refusal(setup.checked, shown, events[0].data, side)
        if refusal is not None:
            raise ActionRefused(409, f"run {setup.run_id} cannot be resumed: {refusal}")
        return setup

    def start_onboard(
        self,
        user: str,
        procedure_name: str,
        binding_name: str,
        mode_name: str,
        *,
        rehearsal: bool = False,
        approver: SecondOperator | None = None,
        proposal: int | None = None,
        confirm_manual: bool = False,
    ) -> str:
        """Start an onboard run ("run on the habitat"), handed to the binding's supervisor or to a runner started
        here (onboard_launch.py); the run's id once the habitat accepted it. Commands that need a second operator's
        approval go up approved by ``approver`` (else ActionRefused 409 lists them in ``approvals_needed``);
        ActionRefused says what to fix. ``proposal``: the agent's proposal ``user`` accepted (``run --proposal``);
        ``confirm_manual``: the habitat marks manual instructions done."""
        mode = mode_named(mode_name)
        path = self.catalog.procedure_path(procedure_name)
        setup = self._setup(procedure_name, binding_name, rehearsal=rehearsal)
        checked, side = setup.checked, setup.side
        points = approval_points(checked, side.approvals)
        if points and approver is None:
            main = Path(checked.procedure.path).resolve()
            raise ActionRefused(
                409,
                f"{self.catalog.shown(procedure_name)} goes up to the habitat only approved: "
                f"{missing_approvals_text(points, main, side.approvals)}; a second operator approves them here",
                {"approvals_needed": [point.describe(main) for point in points]},
            )
        binding = self.catalog.binding_path(binding_name)
        if self.via_supervisor:  # handed from this process to the binding's supervisor: no runner
            start = partial(hand_onboard, setup, binding, self.audit_log, mode=mode)
        else:  # a runner of its own on this host supervises it
            start = partial(
                launch_onboard,
                path,
                binding,
                rehearsal=rehearsal,
                deployments=self.catalog.deployments,
                autonomous=mode is Mode.AUTONOMOUS,
                db_url=self.audit_log.url,
                sysreps=self.catalog.sysreps,
            )
        rosbridge, approving = self.rosbridge_url_for(binding_name), approver if points else None
        try:
            return start(
                user=user, approver=approving, rosbridge=rosbridge, proposal=proposal, confirm_manual=confirm_manual
            )
        except LaunchRefused as exc:
            raise ActionRefused(
                502, f"{procedure_name} did not start on the habitat:\n{exc}", {"ended": exc.ended}
            ) from None

    def resume(self, user: str, run_id: str, binding_name: str, mode_name: str) -> LiveRun:
        """Continue a stopped or interrupted run from its log on ``binding_name``; ActionRefused says why not."""
        mode = mode_named(mode_name)
        if self.live(run_id) is not None:  # (a run that has just ended is released in a moment)
            raise ActionRefused(
                409, f"run {run_id} is live on this server (or ending): resume it once it shows as stopped"
            )
        record = self.hosting.record(run_id)
        if record is not None and record.alive:
            raise ActionRefused(409, f"run {run_id} is live on {record.host}: act on it as on any live run")
        if record is not None and self.hosting.unsupervised(record):  # a second executor would fork its record
            raise ActionRefused(409, f"run {run_id} runs on the habitat: attach a supervisor to it (runs list)")
        events = self.past_events(run_id)
        status = fold_events(run_id, events).status
        if status == "completed":
            raise ActionRefused(409, f"run {run_id} is completed: there is nothing to resume")
        start = run_start(events)
        procedure_name = Path(start.path if start else "").name
        setup = self._setup(procedure_name, binding_name, events=events)
        gateway = self._gateway(setup, binding_name)
        try:
            executive = setup.resumed(gateway, self.audit_log, events, user, mode=mode, control=self.control)
        except (OperatorActionError, ValueError) as exc:
            gateway.close()
            raise ActionRefused(409, f"run {run_id} cannot be resumed: {exc}") from None
        live = self._hold(executive, gateway, setup.checked, binding_name, events[0].actor, history=events)
        live.catch_up(self.audit_log.events(run_id))  # what the executive recorded before the listener was attached
        log.info("%s resumed run %s of %s (%s, %s)", user, run_id, procedure_name, binding_name, mode.value)
        return live

    def _check(self, procedure_name: str) -> CheckedProcedure:
        """The checked procedure, with its SysReps (ActionRefused 422 listing its problems)."""
        try:
            return check_procedure(self.catalog.procedure_path(procedure_name), self.sysreps())
        except ProcedureError as exc:
            raise ActionRefused(422, "the procedure has problems and cannot start:\n" + str(exc)) from None

    def _gateway(self, setup: RunSetup, binding_name: str) -> SystemGateway:
        """An open gateway that serves every system the procedure uses."""
        binding = self.catalog.binding_path(binding_name)
        try:
            gateway = open_gateway(str(binding), rosbridge_url=self.rosbridge_url_for(binding_name))
        except Exception as exc:  # the host's errors (bad binding, no jar, no rosbridge) refuse the start
            log.exception("opening %s", binding)
            raise ActionRefused(
                502, f"cannot reach the systems of {binding_name}: {type(exc).__name__}: {exc}"
            ) from None
        unserved = setup.unserved(gateway)
        if unserved is not None:
            gateway.close()
            raise ActionRefused(422, unserved, rule=RefusalRule.BINDING_SERVES)
        return gateway

    def _hold(
        self,
        executive: Executive,
        gateway: SystemGateway,
        checked: CheckedProcedure,
        binding_name: str,
        started_by: str,
        history: list[Event] | None = None,
    ) -> LiveRun:
        """Keep a run as live here, with a camera feed when the server has a camera to watch."""
        feed = None
        camera = self.camera.camera_for(binding_name)
        if camera is not None and CameraFeed.available(gateway):
            feed = CameraFeed(gateway, camera, period=self.camera.period)
        run_id = executive.run_id
        live = LiveRun(
            executive,
            gateway,
            checked.procedure,
            binding=binding_name,
            started_by=started_by,
            sysreps=dict(checked.sysreps),
            camera_feed=feed,
            history=history,
            host=self.hosting.host,
            on_change=lambda: self.hosting.changed(run_id),
        )
        with self._lock:  # live here before its host row exists: the listing never sees a row without it
            self._live[run_id] = live
        try:
            self.hosting.claim(
                run_id,
                binding=binding_name,
                started_by=started_by,
                procedure_view=live.procedure_view,
                source=live.published_view,
            )
        except HostedElsewhere as exc:  # another console resumed it a moment ago
            with self._lock:
                self._live.pop(run_id, None)
            _release(live)
            raise ActionRefused(409, str(exc)) from None
        executive.add_listener(lambda event: self._on_end(run_id, event))
        self.list_watchers.wake()
        return live

    def _drop(self, live: LiveRun) -> None:
        """Forget a run that did not start after all."""
        with self._lock:
            self._live.pop(live.run_id, None)
        self._unhost(live.run_id)
        _release(live)

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
            self._unhost(run_id)

    def _unhost(self, run_id: str) -> None:
        try:
            self.hosting.release(run_id)
        except SQLAlchemyError:  # its lease runs out instead: other consoles then show it interrupted
            log.exception("releasing the host row of run %s", run_id)
        self.list_watchers.wake()

    def _lost(self, run_id: str, reason: str) -> None:
        """Another process claimed a run hosted here (this console's lease ran out): let go of it."""
        with self._lock:
            live = self._live.pop(run_id, None)
        if live is None:
            return
        try:
            # the run goes on elsewhere: what it added is that host's to use
            live.executive.stop("web-server", f"this console lost the run: {reason}", take_back=False)
        except Exception:  # its log is another host's now: the stop may well not be recordable
            log.exception("stopping run %s after losing it", run_id)
        threading.Thread(target=_release, args=(live,), name=f"lost-{run_id}", daemon=True).start()

    def live(self, run_id: str) -> LiveRun | None:
        with self._lock:
            return self._live.get(run_id)

    def view(self, run_id: str) -> RunView | None:
        """The live run, hosted here or elsewhere (None: not live anywhere, a past run)."""
        live = self.live(run_id)
        if live is not None:
            return live
        with self._lock:
            known = self._remote.get(run_id)
        if known is not None and not known.retired:
            return known
        record = self.hosting.record(run_id)
        if record is None or not record.alive or record.host_id == self.hosting.host_id:
            return None
        remote = RemoteRun(run_id, self.audit_log, self.hosting)
        with self._lock:
            known = self._remote.get(run_id)
            if known is None or known.retired:
                self._remote[run_id] = remote
            else:
                remote = known
        remote.refresh()
        return None if remote.retired else remote

    def let_go(self, run: RunView) -> None:
        """A browser stopped watching ``run``: forget a remote run nobody here watches any more."""
        if isinstance(run, RemoteRun) and not run.watched():
            with self._lock:
                if self._remote.get(run.run_id) is run:
                    del self._remote[run.run_id]

    def host_record(self, run_id: str) -> HostRecord | None:
        return self.hosting.record(run_id)

    def act(self, run_id: str, account: Account, request: ActionRequest) -> Any:
        """Carry out an operator action: here if the run is hosted here, else forwarded to its host
        (each refuses an observer's, and records it in the run's log)."""
        live = self.live(run_id)
        if live is not None:
            return perform_action(live.executive, account, request)
        record = self.hosting.record(run_id)
        if record is None or not record.alive:
            if not account.may_act:  # no live run to record it in
                raise ActionRefused(403, f"{account.user} is an {account.role.value}: observers may watch, not act")
            raise ActionRefused(
                404, f"run {run_id!r} is not live on any console (past and interrupted runs are read-only)"
            )
        answer = self.forwarding.forward(run_id, record.host_id, account.user, request.to_json())
        if not answer.ok:
            raise ActionRefused(answer.status, str(answer.body.get("error", "refused by the run's host")))
        return answer.body.get("result")

    def _perform_forwarded(self, request: ForwardedAction) -> Answer:
        live = self.live(request.run_id)
        return perform_forwarded(live.executive if live else None, self.accounts, request, self.hosting.host)

    def _notice(self, notice: ChangeNotice) -> None:
        """Change-feed subscriber (its thread): mark what changed and wake who shows it."""
        if notice.channel == "resync":
            with self._lock:
                self._starts, remotes = None, list(self._remote.values())
                self._statuses.clear()
            for each in remotes:
                each.events_appended()
                each.host_changed()
            self.list_watchers.wake()
            return
        if notice.channel == "events":
            _seq, kind, run_id = (notice.payload.split(" ", 2) + ["", ""])[:3]
            with self._lock:
                following = self._remote.get(run_id)
                if kind in _LISTED:
                    self._statuses.pop(run_id, None)
                    if kind == EventKind.RUN_STARTED.value:
                        self._starts = None
            if following is not None:
                following.events_appended()
            if kind in _LISTED:
                self.list_watchers.wake()
        elif notice.channel == "hosts":
            with self._lock:
                hosted = self._remote.get(notice.payload)
            if hosted is not None:
                hosted.host_changed()
            self.list_watchers.wake()

    def past_events(self, run_id: str) -> list[Event]:
        events = self.audit_log.events(run_id)
        if not events:
            raise ActionRefused(404, f"no run {run_id!r} in the audit log")
        return events

    def listing(self, limit: int = 100) -> list[dict[str, Any]]:
        """The newest runs in the audit log with their status and host: live here or on another
        console (active, or finished since), or as their log ends (completed, stopped, or
        interrupted: no end recorded; ``host_lost`` when its host's lease ran out)."""
        with self._lock:
            live = dict(self._live)
            starts = self._starts
        if starts is None:
            starts = self.audit_log.starts()
            with self._lock:
                self._starts = starts
        hosts = self.hosting.records()
        rows = []
        for run_id, started, data in list(reversed(starts))[:limit]:
            entry: dict[str, Any] = {
                "run_id": run_id,
                "started": started.isoformat(),
                "procedure": data.get("procedure", ""),
                "rehearsal": data.get("rehearsal") is True,  # the list marks a rehearsal as the run's header does
            }
            record = hosts.get(run_id)
            if run_id in live:
                snapshot = live[run_id].executive.snapshot()
                entry.update(
                    status=snapshot.status.value,
                    mode=snapshot.mode.value,
                    started_by=live[run_id].started_by,
                    live=snapshot.status is RunStatus.ACTIVE,
                    host=self.hosting.host,
                    hosted_here=True,
                    approval=snapshot.approval if snapshot.hold is Hold.APPROVAL else None,
                )
            elif record is not None and record.alive and record.host != self.hosting.host:
                # hosted by another console; a row of this console's without its live run is one
                # whose release has not reached the database yet: the log says how it ended
                entry.update(
                    status=record.status,
                    mode=record.mode,
                    started_by=record.started_by,
                    live=record.status == RunStatus.ACTIVE.value,
                    host=record.host,
                    hosted_here=False,
                    approval=self._approval_wanted(run_id) if record.status == RunStatus.ACTIVE.value else None,
                )
            else:
                entry.update(status=self._logged_status(run_id), live=False)
                if record is not None and entry["status"] == "interrupted":
                    entry["host_lost"] = {"host": record.host, "since": record.lease_until.isoformat()}
                    entry.update(self.hosting.unsupervised(record))  # an onboard run: Attach
            rows.append(entry)
        return rows

    def _approval_wanted(self, run_id: str) -> dict[str, Any] | None:
        """The request for a second operator's approval a run hosted elsewhere waits on, as its
        host last published it (None: it waits on none)."""
        published = self.hosting.published(run_id)
        state = published[2].get("state") if published is not None else None
        if not isinstance(state, dict) or state.get("hold") != Hold.APPROVAL.value:
            return None
        approval = state.get("approval")
        return approval if isinstance(approval, dict) else None

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
                    # resumable, so it keeps what it added (a resume goes on with it)
                    live.executive.stop("web-server", "the web server shut down", take_back=False)
                except Exception:
                    log.exception("stopping run %s", live.run_id)
            _release(live)
            self._unhost(live.run_id)
        self.feed.close()
        self.forwarding.close()
        self.hosting.close()
        self.control.close()


def _not_started(procedure_name: str, exc: OperatorActionError) -> ActionRefused:
    """A 409 for a start the executive refused; with who controls the robot, so the page can offer a takeover."""
    holder = exc.holder if isinstance(exc, RobotControlled) else None
    details = (
        {
            "controlled_by": {
                "robot": holder.robot,
                "run_id": holder.run_id,
                "user": holder.user,
                "since": holder.since.isoformat(),
            }
        }
        if holder
        else None
    )
    return ActionRefused(409, f"{procedure_name} not started: {exc}", details, rule=exc.rule)


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
