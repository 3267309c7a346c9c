"""A run driven outside a console (``caretaker run``) hosted as a console hosts one.

The process that runs a run's executive is its host (:mod:`ground.run_hosts`), whether it
is a console or a runner at a terminal. A runner that wraps its run in a :class:`TerminalHost`
claims the run in the ground database, publishes its view there, and performs the operator
actions that consoles forward to it (as the operator who acted, role checked against the
accounts), so every console shows the run live and an operator may act on it from any console.

Use::

    host = TerminalHost(audit_log, binding=binding_name)
    host.check_free(run_id)                  # before resuming: refuses a run live on another host
    executive = Executive(...)               # or Executive.resume(...)
    host.host(executive, gateway, checked, started_by=user)
    ...                                      # the run
    host.close()                             # the runner stops (an ended run is let go of at once)

An onboard run (``caretaker run --onboard``) is hosted the same way by the runner that supervises
it: :meth:`TerminalHost.host_onboard` publishes its :class:`~console.onboard_view.OnboardView`, and
an action forwarded to it goes up the link to the habitat (:func:`console.actions.perform_onboard`).
"""

from __future__ import annotations

import logging
import os
import socket
import threading

from sqlalchemy.exc import SQLAlchemyError

from console.accounts import AccountStore
from console.actions import OnboardSend, perform_forwarded, perform_onboard
from console.live_run import LiveRun
from console.onboard_view import OnboardView
from ground.action_requests import ActionRequests, Answer, ForwardedAction
from ground.change_feed import open_change_feed
from ground.run_hosts import DEFAULT_LEASE_S, HostedElsewhere, RunHosting
from pride.events import Event, EventKind
from pride.executive import Executive
from pride.systems import SystemGateway
from procedure_language.lint import CheckedProcedure
from records.audit_log import AuditLog

__all__ = ["HostedElsewhere", "TerminalHost"]

log = logging.getLogger(__name__)


class TerminalHost:
    """One runner's run, hosted in the ground database for the consoles."""

    def __init__(
        self,
        audit_log: AuditLog,
        *,
        binding: str,
        lease: float = DEFAULT_LEASE_S,
        name: str | None = None,
        onboard: bool = False,
        operator: str | None = None,
        accounts: AccountStore | None = None,
    ) -> None:
        """``name``: how consoles name this runner (default ``runner HOST pid PID``, and ``for
        OPERATOR`` with an ``operator``, who answers at it: a refused attach names them); ``onboard``:
        it will host an onboard run, whose actions each wait for the habitat's answer side by side;
        ``accounts``: the process's accounts, shared by the runs it hosts (else its own, closed with it)."""
        self.binding = binding
        self._audit_log = audit_log
        self._own_accounts = accounts is None
        self._accounts = accounts or AccountStore(audit_log.url)
        whose = f" for {operator}" if operator else ""
        self.hosting = RunHosting(
            audit_log.engine, host=name or f"runner {socket.gethostname()} pid {os.getpid()}{whose}", lease=lease
        )
        self._live: LiveRun | None = None
        self._onboard: tuple[OnboardView, OnboardSend] | None = None
        self._forwarding = ActionRequests(
            audit_log.engine,
            host_id=self.hosting.host_id,
            console=self.hosting.host,
            perform=self._perform,
            aside=onboard,
        )
        self._feed = open_change_feed(audit_log.engine)
        self._feed.subscribe(self._forwarding.notice)

    def check_free(self, run_id: str) -> None:
        """HostedElsewhere if a console or runner holds a live claim on ``run_id`` (do not resume it here)."""
        record = self.hosting.record(run_id)
        if record is not None and record.alive and record.host_id != self.hosting.host_id:
            raise HostedElsewhere(record)

    def host(
        self,
        executive: Executive,
        gateway: SystemGateway,
        checked: CheckedProcedure,
        *,
        started_by: str,
        history: list[Event] | None = None,
    ) -> None:
        """Claim the run and start publishing it; HostedElsewhere if another process claimed it first."""
        run_id = executive.run_id
        live = LiveRun(
            executive,
            gateway,
            checked.procedure,
            binding=self.binding,
            started_by=started_by,
            sysreps=dict(checked.sysreps),
            history=history,
            host=self.hosting.host,
            on_change=lambda: self.hosting.changed(run_id),
        )
        self.hosting.claim(
            run_id,
            binding=self.binding,
            started_by=started_by,
            procedure_view=live.procedure_view,
            source=live.published_view,
        )
        self._live = live
        executive.add_listener(self._on_event)

    def host_onboard(self, view: OnboardView, send: OnboardSend) -> None:
        """Claim an onboard run and publish what the ground hears of it; forwarded actions go to ``send``."""
        self.hosting.claim(
            view.run_id,
            binding=self.binding,
            started_by=view.started_by,
            procedure_view=view.procedure_view,
            source=view.published_view,
        )
        self._onboard = (view, send)

    def changed(self, run_id: str) -> None:
        """The hosted run's view changed (an onboard view calls it): publish it soon."""
        self.hosting.changed(run_id)

    def _on_event(self, event: Event) -> None:
        """An executive listener (its lock held): once the run ended, let go of it on a thread of its own."""
        if event.kind in (EventKind.RUN_COMPLETED, EventKind.RUN_STOPPED):
            threading.Thread(target=self._release, name=f"release-{event.run_id}", daemon=True).start()

    def _release(self) -> None:
        live, self._live = self._live, None
        onboard, self._onboard = self._onboard, None
        run_id = live.run_id if live is not None else onboard[0].run_id if onboard is not None else None
        if run_id is None:
            return
        try:
            self.hosting.release(run_id)
        except SQLAlchemyError:  # its lease runs out instead
            log.exception("releasing the host row of run %s", run_id)

    def _perform(self, request: ForwardedAction) -> Answer:
        onboard = self._onboard
        if onboard is not None and onboard[0].run_id == request.run_id:
            return perform_onboard(onboard[1], self._accounts, request)
        live = self._live
        executive = live.executive if live is not None and live.run_id == request.run_id else None
        return perform_forwarded(executive, self._accounts, request, self.hosting.host)

    def close(self) -> None:
        """Stop hosting: the run's row goes (consoles then read the run from its log), but for an
        onboard run that goes on on the habitat: its lease ends now and its row stays, saying
        who supervised it, so the consoles offer to attach a new supervisor (:mod:`console.attach`)."""
        self._feed.close()
        self._forwarding.close()
        onboard = self._onboard
        self.hosting.close()
        if onboard is not None and onboard[0].goes_on():
            self._onboard = None
            try:
                self.hosting.lapse(onboard[0].run_id)
            except SQLAlchemyError:  # its lease runs out instead
                log.exception("ending the lease of run %s", onboard[0].run_id)
        else:
            self._release()
        if self._own_accounts:
            self._accounts.close()
