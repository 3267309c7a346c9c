"""``caretaker run --onboard --via-supervisor``: hand the unit to the supervisor that keeps the habitat's
session open (``caretaker supervise``), and follow the run from the ground database.

The runner builds and checks the unit as ``--onboard`` does, then hands it over
(:mod:`records.onboard_handoffs`) instead of opening a session to the habitat: a supervisor of the
unit's binding takes it, uplinks it at once on its open session and keeps the run's record in
the audit log of the same database. The runner shows that record here as it is stored (woken by
the database's change notices) and ends with the run. If no supervisor takes the run within
``--supervisor-within`` seconds the runner withdraws it and says so; nothing went up.
Ctrl-C stops following, never the run: its supervisor goes on (the consoles show it). With
``--no-follow`` the runner ends as soon as the habitat took the unit and leaves the run to its
supervisor, which hosts it for the consoles (a console hands its starts the same way, in its own
process: :func:`console.onboard_launch.hand_onboard`).
"""

from __future__ import annotations

import argparse
import sys
from datetime import UTC, datetime

from caretaker.terminal import LeftBehind, ProgressPrinter, TerminalLines
from ground.handed_run import HandedRun
from ground.run_hosts import DEFAULT_LEASE_S, RunHosting
from onboard.unit import Unit
from pride.executive import RunStatus
from pride.phrasing import Wording
from procedure_language.lint import CheckedProcedure
from records.audit_log import DEFAULT_DB, AuditLog
from records.onboard_handoffs import DETACHED, ENDED, UPLINKED, Handoff

__all__ = ["hand_to_supervisor"]


def hand_to_supervisor(args: argparse.Namespace, audit: AuditLog, unit: Unit, checked: CheckedProcedure) -> int:
    """Hand ``unit`` to a supervisor through ``audit``'s database and follow its run to the end."""
    terminal = TerminalLines(sys.stdout)  # as it is now (a test captures it)
    printer = ProgressPrinter(checked.procedure, terminal, Wording(checked.sysreps, args.raw))
    left_behind = LeftBehind(terminal)
    run_id = unit.run_id
    db = "" if args.db == DEFAULT_DB else f" --db {args.db}"
    handed = HandedRun(audit, run_id)
    try:
        handed.hand(binding=unit.binding, unit_json=unit.to_json(), user=unit.user, at_consoles=args.at_consoles)
        terminal.say(
            f"handed run {run_id} to the supervisors of {unit.binding}; waiting up to "
            f"{args.supervisor_within:g} s for one to take it"
        )
        if handed.taken(args.supervisor_within) is None:
            terminal.say(
                f"caretaker run: no supervisor took run {run_id} within {args.supervisor_within:g} s: withdrawn, "
                f"nothing went up (is `caretaker supervise --binding {args.binding}{db}` running?)"
            )
            return 2
        handoff = _followed(handed, audit, printer, left_behind, terminal, until_ready=args.no_follow)
    except KeyboardInterrupt:
        if handed.handoffs.withdraw(run_id):
            terminal.say(f"\n  run {run_id} withdrawn before a supervisor took it: nothing went up")
        else:
            terminal.say(f"\n  stopped following run {run_id}: its supervisor goes on (the consoles show it)")
        return 130
    finally:
        handed.close()
    if args.no_follow and handoff.state not in (ENDED, DETACHED):
        terminal.say(f"followed no further: {handoff.supervisor} keeps its record and hosts it for the consoles")
        return 0
    if handoff.state == DETACHED:
        terminal.say(f"its supervisor, {handoff.supervisor}, no longer follows it: {handoff.message}")
        terminal.say(f"follow it again: caretaker run --attach {run_id} --binding {args.binding}{db} --user USER")
    elif handoff.result != RunStatus.COMPLETED.value and handoff.message:
        terminal.say(f"caretaker run: {handoff.message}")
    result = handoff.result or handoff.state
    terminal.say(f"RESULT {result} run {run_id} (report: caretaker report {run_id}{db})")
    return 0 if result == RunStatus.COMPLETED.value else 1


def _followed(
    handed: HandedRun,
    audit: AuditLog,
    printer: ProgressPrinter,
    left_behind: LeftBehind,
    terminal: TerminalLines,
    *,
    until_ready: bool = False,
) -> Handoff:
    """Show the run's record as its supervisor stores it, until supervision ends (``until_ready``: until
    the habitat took the unit); the handoff then.
    A supervisor whose lease on the run ran out is gone (killed, or it lost the database): the
    handoff is then ``detached`` here, as the supervisor would have left it."""
    run_id, handoffs = handed.run_id, handed.handoffs
    hosting = RunHosting(audit.engine, host=f"runner following {run_id}")  # it reads the supervisor's lease
    try:
        head = 0
        ready = False
        handoff = handoffs.get(run_id)
        assert handoff is not None  # handoffs are never removed
        terminal.say(f"taken by {handoff.supervisor}: it uplinks the unit on the session it keeps open")
        while True:
            handoff = handoffs.get(run_id)
            assert handoff is not None
            events = audit.events(run_id, after=head)  # read after the state: all of an ended run's events
            if not ready and (handoff.state == UPLINKED or events):
                terminal.say(f"the habitat took the unit: it runs {run_id}")
                terminal.say(f"READY run {run_id}")
                ready = True
                if until_ready:
                    return handoff
            for event in events:
                printer(event)
                left_behind(event)
                head = event.seq
            if handoff.state in (ENDED, DETACHED):
                return handoff
            lease = hosting.record(run_id)
            if lease is not None and not lease.alive:
                gone = (
                    f"its lease on the run ran out at {lease.lease_until:%H:%M:%S}Z (it stopped, or lost the "
                    "database); the run goes on on the habitat"
                )
                # the supervisor whose lease it was: not one that took the run over meanwhile
                handoffs.end(run_id, detached=True, result=DETACHED, message=gone, supervisor=handoff.supervisor)
                continue  # read as it ended: detached, or ended just before
            # a live supervisor renews its lease every second: a check as it runs out
            until = (lease.lease_until - datetime.now(UTC)).total_seconds() if lease else DEFAULT_LEASE_S
            handed.wait(min(max(until, 0.5), DEFAULT_LEASE_S))
    finally:
        hosting.close()
