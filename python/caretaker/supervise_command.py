"""``caretaker supervise``: a ground process that keeps its session to the habitat open and supervises
the onboard runs handed to it.

``caretaker run --onboard`` opens a session of its own to the habitat for each run: across the
link that costs the opening's round trips (TCP, TLS, the WebSocket upgrade, the login) before
the unit can go up. A supervisor opens the habitat's session once, keeps it alive (keepalive
pings; when it drops, :class:`~rosbridge_wire.client.RosbridgeClient` opens it again, and the
runs it follows catch up) and takes the runs handed to it through the ground database
(``caretaker run --onboard --via-supervisor``, :mod:`records.onboard_handoffs`): those whose
unit names the binding it serves, each taken by one supervisor. For each it signs and uplinks
the unit on the open session, with the requests for its events right behind it, hosts the run
for the consoles under a lease (the lease an attach respects: one supervisor per run), keeps its
record in the audit log and says how it ended in the handoff, where the runner that handed it
reads it. It learns of handed runs from the database's change notices (LISTEN on PostgreSQL; on
SQLite the change feed reads the file).

SIGTERM (or Ctrl-C) ends supervision, never a run: each goes on on the habitat, its handoff says
``detached``, and ``caretaker run --attach RUN`` (or the consoles' Attach) follows it again.

Several supervisors of one binding, on several hosts, share its runs through the database: each
run is held by one, under its lease. A supervisor that stops or dies leaves its runs detached
or with its lease run out; another supervisor of the binding takes each over (one does: the
takeover is a conditional UPDATE) and follows it as an attach does, catching the ground's record
up from the last event stored, hash for hash. A run taken but not yet uplinked is uplinked again:
the habitat answers the same signed unit with its first answer and starts nothing twice.
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import contextlib
import os
import signal
import socket
import sys
from collections.abc import Callable, Coroutine
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from typing import Any

from sqlalchemy.exc import SQLAlchemyError

from caretaker.command_options import load_sysreps, sysrep_option
from caretaker.onboard_hosting import OnboardHosting, unit_checked
from console.accounts import AccountStore
from console.catalog import rosbridge_for, rosbridge_overrides
from console.terminal_host import HostedElsewhere, TerminalHost
from datafile import DataFileError
from ground.change_feed import ChangeNotice, open_change_feed
from ground.run_hosts import DEFAULT_LEASE_S, live_runs
from onboard.downlink import DownlinkError, OnboardSupervisor, Supervision
from onboard.unit import Unit, UnitError
from procedure_language.binding import read_binding
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import CheckedProcedure
from procedure_language.sysrep import SysRep, SysRepError
from records.audit_chain import utc
from records.audit_log import DEFAULT_DB, AuditLog, AuditLogUnavailable
from records.audit_schema import AuditSchemaError
from records.onboard_handoffs import DETACHED, TAKEN, Handoff, OnboardHandoffs
from rosbridge_wire.client import Endpoint, RosbridgeClient

__all__ = ["Supervisor", "main", "serve_all"]

Say = Callable[[str], None]


class Supervisor:
    """Takes the runs handed to ``binding``'s supervisors and supervises each on one session to the
    habitat: ``client``'s, or (by default) one it opens itself and keeps open until it stops."""

    def __init__(
        self,
        endpoint: Endpoint,
        binding: str,
        audit: AuditLog,
        sysreps: dict[str, SysRep],
        client: RosbridgeClient | None = None,
        *,
        lease: float = DEFAULT_LEASE_S,
        accounts: AccountStore | None = None,
    ) -> None:
        self.setups: asyncio.Semaphore | None = None  # runs set up at once (_setting_up)
        self.accounts = accounts  # the process's, shared by the runs it hosts (checked at each forwarded action)
        self.endpoint = endpoint
        self.lease = lease  # how long a run's host lease lasts unrenewed: a supervisor gone after it
        self.binding = binding
        self.audit = audit
        self.sysreps = sysreps
        self.name = f"supervisor {socket.gethostname()} pid {os.getpid()}"  # as the consoles name it
        self.handoffs = OnboardHandoffs(audit.engine)
        self._own_client = client is None
        self.client = client or RosbridgeClient(endpoint, name="caretaker-supervise", on_state=self._session)
        self._runs: set[asyncio.Task[None]] = set()
        self._held: set[str] = set()  # the runs this supervisor follows
        self._stopping = asyncio.Event()  # SIGTERM: every run's supervision ends, the runs go on
        self._serving = False  # READY said: the session was open
        self._lost = False  # the session dropped and is being opened again

    def stop(self) -> None:
        """End supervision (SIGTERM, Ctrl-C): the runs go on on the habitat, their handoffs ``detached``."""
        self._stopping.set()

    async def serve(self, *, signals: bool = True) -> int:
        """Supervise until :meth:`stop` (``signals``: SIGTERM and Ctrl-C stop it; a process serving
        several bindings handles them once for all, :func:`serve_all`)."""
        loop = asyncio.get_running_loop()
        handed = asyncio.Event()
        for signum in (signal.SIGTERM, signal.SIGINT) if signals else ():
            loop.add_signal_handler(signum, self.stop)

        def notice(change: ChangeNotice) -> None:  # the feed's thread
            if change.channel in ("handoffs", "resync"):
                loop.call_soon_threadsafe(handed.set)

        if self._own_client:
            self.client.start()
        feed = open_change_feed(self.audit.engine)
        feed.subscribe(notice)
        try:
            await _first(self.client.ready.wait(), self._stopping.wait())
            if self._stopping.is_set():
                return 0
            await asyncio.to_thread(feed.connected.wait, 30)  # listening before the first look: no notice missed
            self._serving = True
            print(f"READY supervise {self.binding} {self.endpoint.url} as {self.name}", flush=True)
            while not self._stopping.is_set():
                handed.clear()
                try:  # the database is read off the loop: the runs followed on it do not wait for it
                    for handoff in await asyncio.to_thread(self.handoffs.waiting, self.binding):
                        if await asyncio.to_thread(self.handoffs.take, handoff.run_id, self.name):
                            self._start(loop, handoff, attaching=False)
                    for handoff in await asyncio.to_thread(self._orphans):
                        if await asyncio.to_thread(self.handoffs.take_over, handoff, self.name):
                            print(
                                f"{handoff.run_id}: TAKEN OVER from {handoff.supervisor} ({handoff.state})", flush=True
                            )
                            self._start(loop, handoff, attaching=handoff.state != TAKEN)
                except SQLAlchemyError as exc:  # looked at again when the feed is back (resync)
                    print(f"caretaker supervise: cannot read the handed runs: {exc}", file=sys.stderr, flush=True)
                # a lease that runs out sends no notice: look again within a lease's tenth
                await _first(handed.wait(), self._stopping.wait(), asyncio.sleep(self.lease / 10))
            if self._runs:
                await asyncio.wait(self._runs)
            print("supervision stopped: the runs go on on the habitat", flush=True)
            return 0
        finally:
            for signum in (signal.SIGTERM, signal.SIGINT) if signals else ():
                loop.remove_signal_handler(signum)
            feed.close()
            if self._own_client:
                await self.client.close()

    def _start(self, loop: asyncio.AbstractEventLoop, handoff: Handoff, *, attaching: bool) -> None:
        task = loop.create_task(self._supervise(handoff, attaching=attaching))
        self._runs.add(task)
        task.add_done_callback(self._runs.discard)
        self._held.add(handoff.run_id)
        task.add_done_callback(lambda _: self._held.discard(handoff.run_id))

    def _orphans(self) -> list[Handoff]:
        """This binding's runs whose supervisor is gone: detached, or its lease on the run ran out
        (taken and not yet held: once a lease's time has passed since it was taken)."""
        found = [h for h in self.handoffs.supervised(self.binding) if h.run_id not in self._held]
        live = live_runs(self.audit.engine, [h.run_id for h in found])
        now = datetime.now(UTC)
        return [
            h
            for h in found
            if h.state == DETACHED
            or (h.run_id not in live and (h.taken_at is None or (now - utc(h.taken_at)).total_seconds() > self.lease))
        ]

    def _session(self, state: str) -> None:
        """The session's changes, said once each (a reconnecting client says so at every try)."""
        if state == "connected" and self._lost:
            print("SESSION open again", flush=True)
        elif state == "reconnecting" and self._serving and not self._lost:
            print(f"SESSION lost: opening it again ({self.endpoint.url})", flush=True)
        self._lost = state == "reconnecting" and self._serving

    async def _supervise(self, handoff: Handoff, *, attaching: bool) -> None:
        """Uplink one handed unit on the open session (``attaching``: catch up with the run it
        started, taken over) and follow its run until it ends or supervision stops.

        What blocks (linting the unit, the database, opening the run's host) goes to a thread: the
        loop follows every other run meanwhile, and fifty runs handed at once are fifty lints."""
        run_id = handoff.run_id

        def say(line: str) -> None:
            print(f"{run_id}: {line.strip()}", flush=True)

        say(f"TAKEN from {handoff.handed_by}")
        try:
            unit = Unit.from_json(handoff.unit_json)
            with contextlib.ExitStack() as stack:
                async with self._setting_up():
                    checked = await asyncio.to_thread(stack.enter_context, unit_checked(unit, self.sysreps))
                await self._follow(unit, checked, handoff, say, attaching=attaching)
        except (UnitError, ProcedureError, SysRepError) as exc:
            await self._end(Supervision("refused", run_id, f"the handed unit cannot be supervised here: {exc}"), say)
        except DownlinkError as exc:
            await self._end(Supervision("unknown", run_id, f"the onboard run's record cannot be kept: {exc}"), say)

    async def _follow(
        self, unit: Unit, checked: CheckedProcedure, handoff: Handoff, say: Say, *, attaching: bool
    ) -> None:
        loop = asyncio.get_running_loop()

        def uplinked(_: str) -> None:  # the habitat accepted the unit: the handoff says so (its runner prints READY)
            loop.run_in_executor(None, self.handoffs.uplinked, unit.run_id).add_done_callback(noted)

        def noted(done: asyncio.Future[bool]) -> None:
            if not done.cancelled() and done.exception() is not None:
                say(f"the handoff cannot say that the habitat took the unit: {done.exception()}")

        async with self._setting_up():
            hosting = await asyncio.to_thread(self._hosting, unit, checked, say)
        try:
            try:
                async with self._setting_up():
                    supervisor = await asyncio.to_thread(  # reads what the ground has of the run
                        partial(
                            OnboardSupervisor,
                            self.endpoint,
                            unit,
                            self.audit,
                            on_event=hosting.view.event,
                            say=say,
                            unattended=not handoff.at_consoles,
                            on_news=hosting.news,
                            client=self.client,
                            on_uplinked=uplinked,
                        )
                    )
                    await asyncio.to_thread(hosting.hold, supervisor)
            except HostedElsewhere as exc:  # one supervisor per run: the one that holds it goes on
                await self._end(Supervision("refused", unit.run_id, str(exc)), say)
                return
            # ended before the lease goes: the runner reads how it ended, not a lease run out
            await self._end(await supervisor.supervise(attaching=attaching, detach=self._stopping), say)
        finally:
            await asyncio.to_thread(hosting.close)

    def _setting_up(self) -> asyncio.Semaphore:
        """Held while a run is set up (its lint, its host): fifty handed at once would otherwise be
        fifty threads computing at once, and the threads that renew the runs' leases and store their
        events would wait for the interpreter behind them past a lease. One process-wide limit
        (:func:`serve_all` shares it between the bindings' supervisors)."""
        if self.setups is None:
            self.setups = asyncio.Semaphore(SETTING_UP_AT_ONCE)
        return self.setups

    def _hosting(self, unit: Unit, checked: CheckedProcedure, say: Say) -> OnboardHosting:
        """The run hosted for the consoles as a ground run is: they show it live and forward
        operators' actions here (without a host when the database refuses one: the run goes on)."""
        try:
            host: TerminalHost | None = TerminalHost(
                self.audit, binding=unit.binding, onboard=True, name=self.name, accounts=self.accounts
            )
        except (SQLAlchemyError, AuditSchemaError) as exc:
            say(f"the onboard run is not shown on the consoles: {exc}")
            host = None
        return OnboardHosting(host, unit, checked, say)

    async def _end(self, result: Supervision, say: Say) -> None:
        """Supervision of the run is over: its handoff says how (where its runner reads it)."""
        say(f"ENDED {result.status}{': ' + result.message if result.message else ''}")
        detached = result.status == "detached"
        await asyncio.to_thread(
            partial(
                self.handoffs.end,
                result.run_id,
                detached=detached,
                result=result.status,
                message=result.message,
                supervisor=self.name,
            )
        )


#: Threads that store followed runs' events at once (one pooled database connection each): about
#: half the audit log's pool (5 + 10 overflow), so that a burst of stores leaves connections to
#: the threads that renew the runs' leases (a lease unrenewed for its 10 s is a supervisor gone).
STORE_THREADS = 8
#: Runs set up at once in one supervising process (Supervisor._setting_up).
SETTING_UP_AT_ONCE = 2


async def serve_all(supervisors: list[Supervisor]) -> int:
    """Serve several bindings' supervisors in one process until SIGTERM or Ctrl-C stops them all."""
    loop = asyncio.get_running_loop()
    # the runs' events are stored off the loop, each store waiting for its commit
    loop.set_default_executor(concurrent.futures.ThreadPoolExecutor(STORE_THREADS, thread_name_prefix="store"))

    setups = asyncio.Semaphore(SETTING_UP_AT_ONCE)
    for supervisor in supervisors:
        supervisor.setups = setups

    def stop_all() -> None:
        for supervisor in supervisors:
            supervisor.stop()

    for signum in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(signum, stop_all)
    try:
        return max(await asyncio.gather(*(supervisor.serve(signals=False) for supervisor in supervisors)))
    finally:
        for signum in (signal.SIGTERM, signal.SIGINT):
            loop.remove_signal_handler(signum)


async def _first(*waits: Coroutine[Any, Any, Any]) -> None:
    """Until the first of ``waits`` is over (the others are cancelled)."""
    tasks = [asyncio.ensure_future(wait) for wait in waits]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for task in tasks:
            task.cancel()


def main(argv: list[str] | None = None) -> int:
    """``caretaker supervise --binding FILE [--binding FILE]... [--db URL] [--rosbridge [BINDING=]URL]...``."""
    parser = argparse.ArgumentParser(
        prog="caretaker supervise",
        description="keep each habitat's session open and supervise the onboard runs handed to its binding",
    )
    parser.add_argument(
        "--binding",
        required=True,
        action="append",
        metavar="FILE",
        help="the ground binding of a habitat; repeat for several habitats (one session each, in one process)",
    )
    parser.add_argument(
        "--db",
        default=os.environ.get("CARETAKER_DB", DEFAULT_DB),
        metavar="URL",
        help=f"the ground database the runs are handed through (default $CARETAKER_DB, else {DEFAULT_DB})",
    )
    parser.add_argument(
        "--rosbridge",
        action="append",
        default=[],
        metavar="[BINDING=]URL",
        help="override the rosbridge URL of the binding file BINDING, or of every binding without BINDING=",
    )
    sysrep_option(parser)
    args = parser.parse_args(argv)
    names = [Path(binding).name for binding in args.binding]
    if len(set(names)) != len(names):
        print(
            "caretaker supervise: two --binding files of one name: a handoff names its binding by file name",
            file=sys.stderr,
        )
        return 2
    endpoints = []
    try:
        overrides = rosbridge_overrides(args.rosbridge)
        sysreps = load_sysreps(args.sysrep_dir)
        for binding, name in zip(args.binding, names, strict=True):
            endpoints.append(read_binding(binding).endpoint(rosbridge_for(overrides, name)))
    except (DataFileError, OSError, SysRepError, ValueError) as exc:
        print(f"caretaker supervise: {exc}", file=sys.stderr)
        return 2
    unsigned = [binding for binding, endpoint in zip(args.binding, endpoints, strict=True) if endpoint.secret is None]
    if unsigned:
        print(
            f"caretaker supervise: {', '.join(unsigned)} has no security.secret_file: units are signed with it",
            file=sys.stderr,
        )
        return 2
    try:
        audit = AuditLog(args.db)
    except (AuditSchemaError, AuditLogUnavailable) as exc:
        print(f"caretaker supervise: {exc}", file=sys.stderr)
        return 2
    try:
        accounts = AccountStore(audit.url)
    except (AuditSchemaError, SQLAlchemyError) as exc:
        audit.close()
        print(f"caretaker supervise: {exc}", file=sys.stderr)
        return 2
    try:
        supervisors = [
            Supervisor(endpoint, name, audit, sysreps, accounts=accounts)
            for endpoint, name in zip(endpoints, names, strict=True)
        ]
        return asyncio.run(serve_all(supervisors))
    finally:
        accounts.close()
        audit.close()
