"""``caretaker run --onboard`` and ``caretaker run --attach``: the habitat runs it, this terminal supervises.

The supervising runner keeps the ground's record of an onboard run (a verified copy of the
habitat's chain), shows it at this terminal, hosts it for the consoles and sends operators'
actions up. ``--onboard`` uplinks a new unit first; ``--attach RUN`` takes over a run already on
the habitat whose supervisor stopped: the habitat gives the unit the run started from, the record
is caught up from the last event the ground stored, and supervision goes on. A run has one
supervisor at a time (its host row in the ground database): a second is refused and told who holds it.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from pathlib import Path

from caretaker.command_options import DEFAULT_SYSREP_DIR, load_sysreps, section_of
from caretaker.terminal import LeftBehind, ProgressPrinter, TerminalLines
from datafile import DataFileError
from onboard.downlink import DownlinkError, OnboardSupervisor, unit_for_run
from onboard.unit import UNIT_SERVICE, Unit, UnitError
from pride.accepted_proposal import AcceptedProposal
from pride.approvals import APPROVER_PASSWORD_ENV
from pride.events import Event
from pride.executive import Mode, RunStatus
from pride.phrasing import Wording
from pride.run_section import SectionError
from pride.run_setup import RunSetup
from pride.states import RefusalRule
from procedure_language.binding import read_binding
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import CheckedProcedure
from procedure_language.sysrep import SysRepError
from records.audit_log import DEFAULT_DB, AuditLog
from rosbridge_wire.client import Endpoint, LinkError, RosbridgeClient

__all__ = ["attach", "run_onboard"]


def _endpoint(args: argparse.Namespace) -> Endpoint | None:
    """The habitat's bridge as the binding reaches it, with the link's secret; None (said why) if not."""
    try:
        endpoint = read_binding(args.binding).endpoint(args.rosbridge)
    except (DataFileError, OSError) as exc:
        print(f"caretaker run: cannot open binding {args.binding}: {exc}", file=sys.stderr)
        return None
    if endpoint.secret is None:
        print(
            f"caretaker run: {args.binding} has no security.secret_file: an onboard unit is signed with the "
            "link's secret",
            file=sys.stderr,
        )
        return None
    return endpoint


def run_onboard(
    args: argparse.Namespace,
    setup: RunSetup,
    audit: AuditLog,
    values: dict[str, str],
    approver: str | None,
    proposal: AcceptedProposal | None = None,
) -> int:
    """``caretaker run --onboard``: the habitat runs it; this terminal shows it and keeps its record.
    The commands that need a second operator's approval go up approved by ``approver``; ``proposal``:
    the agent's proposal it answers, named in its record."""
    checked = setup.checked
    if args.resume:
        print("caretaker run: --onboard starts a new onboard run; it does not --resume one", file=sys.stderr)
        return 2
    endpoint = _endpoint(args)
    if endpoint is None:
        return 2
    try:
        unit = unit_for_run(
            setup,
            endpoint,
            binding=Path(args.binding).name,
            user=args.user,
            mode=args.mode or Mode.MANUAL,
            values=values,
            approver=approver,
            proposal=proposal,
            confirm_manual=args.confirm_manual,
            confirm_hazardous=args.confirm_hazardous,
            breakpoints=args.breakpoints,
            section=section_of(args, checked, values),
            lifetime_s=args.unit_lifetime,
        )
    except SectionError as exc:
        print(f"caretaker run: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(
            f"caretaker run: {checked.procedure.path} cannot go up to the habitat: {exc} "
            f"(give --approver USER, their password in ${APPROVER_PASSWORD_ENV})",
            file=sys.stderr,
        )
        return 2
    if args.via_supervisor:  # its session is open already: it uplinks the unit (caretaker supervise)
        from caretaker.via_supervisor import hand_to_supervisor

        return hand_to_supervisor(args, audit, unit, checked)
    return _supervise(args, audit, endpoint, unit, checked, attaching=False)


def attach(args: argparse.Namespace, audit: AuditLog) -> int:
    """``caretaker run --attach RUN``: supervise an onboard run already on the habitat."""
    endpoint = _endpoint(args)
    if endpoint is None:
        return 2
    try:
        found = asyncio.run(_unit_of(endpoint, args.attach))
    except LinkError as exc:
        print(f"caretaker run: the habitat did not give run {args.attach}'s unit: {exc}", file=sys.stderr)
        return 1
    if isinstance(found, str):
        print(f"caretaker run: {found}", file=sys.stderr)
        return 2
    from caretaker.onboard_hosting import unit_checked

    try:
        with unit_checked(found, load_sysreps(args.sysrep_dir)) as checked:
            return _supervise(args, audit, endpoint, found, checked, attaching=True)
    except (ProcedureError, SysRepError) as exc:
        print(
            f"caretaker run: run {args.attach}'s procedure does not lint against this ground's SysReps "
            f"({args.sysrep_dir or DEFAULT_SYSREP_DIR}): {exc}",
            file=sys.stderr,
        )
        return 2


async def _unit_of(endpoint: Endpoint, run_id: str) -> Unit | str:
    """The unit ``run_id`` started from, as the habitat keeps it; or why there is none."""
    client = RosbridgeClient(endpoint, name="caretaker-attach")
    client.start()
    try:
        await asyncio.wait_for(client.opened.wait(), endpoint.light_time.connect_within)
        answer = await client.call(UNIT_SERVICE, {"run_id": run_id}, timeout=client.call_timeout())
    except TimeoutError:
        raise LinkError(UNIT_SERVICE, "no connection to the habitat in time") from None
    finally:
        await client.close()
    text = str(answer.get("unit_json", ""))
    if not text:
        return str(answer.get("message") or f"the habitat has no onboard run {run_id}")
    try:
        return Unit.from_json(text)
    except UnitError as exc:
        return f"the habitat's unit of run {run_id} cannot be read: {exc}"


def _supervise(
    args: argparse.Namespace,
    audit: AuditLog,
    endpoint: Endpoint,
    unit: Unit,
    checked: CheckedProcedure,
    *,
    attaching: bool,
) -> int:
    """Follow the onboard run to its end at this terminal, host it for the consoles, keep its record."""
    terminal = TerminalLines()
    from sqlalchemy.exc import SQLAlchemyError

    from caretaker.onboard_hosting import OnboardHosting
    from console.attach_records import record_attach_refused, record_attached
    from console.terminal_host import HostedElsewhere, TerminalHost
    from records.audit_schema import AuditSchemaError

    def warn(text: str) -> None:
        print(f"caretaker run: {text}", file=sys.stderr)

    printer = ProgressPrinter(checked.procedure, terminal, Wording(checked.sysreps, args.raw))
    left_behind = LeftBehind(terminal)
    # Hosted for the consoles as a ground run is: they show it live and forward operators' actions here.
    try:
        host: TerminalHost | None = TerminalHost(audit, binding=unit.binding, onboard=True, operator=args.user)
    except (SQLAlchemyError, AuditSchemaError) as exc:  # the run goes on; the consoles do not show it live
        warn(f"the onboard run is not shown on the consoles: {exc}")
        host = None
    hosting = OnboardHosting(host, unit, checked, warn)
    if attaching:  # the consoles show the run from its start, not from where this runner caught up
        hosting.view.stored_before(audit.events(unit.run_id))

    def on_event(event: Event) -> None:
        printer(event)
        left_behind(event)
        hosting.view.event(event)

    supervisor = OnboardSupervisor(
        endpoint,
        unit,
        audit,
        on_event=on_event,
        say=terminal.say,
        unattended=not sys.stdin.isatty() and not args.at_consoles,
        on_news=hosting.news,
        operator=args.user,
    )
    try:
        try:
            hosting.hold(supervisor)
        except HostedElsewhere as exc:
            if attaching:  # one supervisor per run: the one that holds it goes on
                warn(f"--attach refused: {exc}")
                record_attach_refused(audit, args.user, unit.run_id, RefusalRule.ONE_SUPERVISOR, str(exc))
                return 2
            warn(f"the onboard run is not shown on the consoles: {exc}")
        if attaching:  # who took it over, and when (the run's own log is the habitat's)
            record_attached(audit, args.user, unit.run_id, host.hosting.host if host else "a runner at a terminal")
        result = asyncio.run(supervisor.attach() if attaching else supervisor.run())
    except DownlinkError as exc:
        warn(f"the onboard run's record cannot be kept: {exc}")
        return 1
    finally:
        hosting.close()
    db = "" if args.db == DEFAULT_DB else f" --db {args.db}"
    if result.status == "detached":
        terminal.say(f"follow it again: caretaker run --attach {unit.run_id} --binding {args.binding}{db} --user USER")
    terminal.say(f"RESULT {result.status} run {unit.run_id} (report: caretaker report {unit.run_id}{db})")
    return 0 if result.status == RunStatus.COMPLETED.value else 1
