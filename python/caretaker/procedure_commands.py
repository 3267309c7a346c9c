"""``caretaker lint``, ``run``, ``report`` and ``db`` (docs/interfaces.md).

Exit codes: 0 success; 1 the procedure has errors, the run stopped, or the run failed;
2 bad command line or environment (missing file, unknown run, gateway cannot serve a system).
"""

from __future__ import annotations

import argparse
import getpass
import logging
import os
import signal
import sys
from datetime import UTC, datetime
from pathlib import Path

from caretaker.command_options import load_sysreps, raw_option, section_of, sysrep_option
from caretaker.terminal import LeftBehind, OperatorConsole, ProgressPrinter, TerminalLines, Unattended
from datafile import DataFileError
from onboard.downlink import UNIT_LIFETIME_S
from pride.approvals import APPROVER_PASSWORD_ENV
from pride.event_payloads import EventDataError
from pride.events import Event, EventKind, run_start
from pride.executive import Mode, OperatorActionError, RunStatus
from pride.gateways import open_gateway
from pride.phrasing import Wording
from pride.robot_sides import RobotSide, robot_side_for
from pride.run_control import RobotControlled
from pride.run_section import SectionError
from pride.run_setup import RunSetup
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import CheckedProcedure, lint_file
from procedure_language.sysrep import SysRep, SysRepError
from records.agent_proposals import ProposalStore
from records.agent_tokens import TokenError, parse_duration
from records.audit_log import DEFAULT_DB, AuditLog, AuditLogUnavailable
from records.audit_schema import AuditSchemaError, head_revision
from records.onboard_handoffs import SUPERVISOR_WITHIN_S
from records.proposal_runs import ProposalNotRunnable, proposal_taken
from records.releases import ReleaseRefused, ReleaseStore, resume_refusal, version_for_run
from records.robot_control import RobotControl

__all__ = ["LeftBehind", "db_main", "lint_main", "report_main", "run_main"]

log = logging.getLogger(__name__)


def lint_main(argv: list[str] | None = None) -> int:
    """``caretaker lint FILE...``: print every problem as file:line:col: message."""
    parser = argparse.ArgumentParser(
        prog="caretaker lint", description="check procedures against their schema and SysReps"
    )
    parser.add_argument("files", nargs="+", metavar="FILE")
    sysrep_option(parser)
    args = parser.parse_args(argv)
    try:
        sysreps = load_sysreps(args.sysrep_dir)
    except SysRepError as exc:
        print(exc, file=sys.stderr)
        return 2
    failed = 0
    for path in args.files:
        problems = lint_file(path, sysreps)
        for problem in problems:
            print(problem)
        if not problems:  # say what was checked, so silence is never mistaken for success
            against = f"{len(sysreps)} SysRep{'' if len(sysreps) == 1 else 's'}"
            print(f"{path}: ok (schema, and every command and telemetry name against {against})")
        failed += bool(problems)
    if failed:
        print(f"{failed} of {len(args.files)} procedure(s) have errors", file=sys.stderr)
    return 1 if failed else 0


def run_main(argv: list[str] | None = None) -> int:
    """``caretaker run PROC --binding FILE --auto|--manual --user NAME ...``."""
    parser = argparse.ArgumentParser(prog="caretaker run", description="run a procedure with PAX")
    parser.add_argument("procedure", nargs="?", metavar="PROC", help="procedure XML (not needed with --resume)")
    parser.add_argument("--binding", required=True, metavar="FILE", help="which plugins serve which SysRep")
    parser.add_argument(
        "--rosbridge", metavar="URL", help="override the binding's rosbridge URL (e.g. ws://127.0.0.1:9091)"
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--auto", action="store_const", const=Mode.AUTONOMOUS, dest="mode", help="PAX runs automatable instructions"
    )
    mode.add_argument(
        "--manual", action="store_const", const=Mode.MANUAL, dest="mode", help="the operator performs every instruction"
    )
    parser.add_argument(
        "--user", required=True, metavar="NAME", help="who runs it (recorded with every operator action)"
    )
    parser.add_argument(
        "--db",
        default=os.environ.get("CARETAKER_DB", DEFAULT_DB),
        metavar="URL",
        help=f"audit log SQLAlchemy URL (default $CARETAKER_DB, else {DEFAULT_DB}: a URL with a password "
        "is better in the environment than on a command line others can read)",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="answer the record NAME; with --from, also what the skipped steps would have bound (a record, or "
        "a command result's value as RESULT.VALUE)",
    )
    parser.add_argument(
        "--from", dest="from_step", metavar="STEP", help="start at this step (its id or number), not the first"
    )
    parser.add_argument("--to", dest="to_step", metavar="STEP", help="end the run after this step")
    parser.add_argument("--confirm-manual", action="store_true", help="mark manual instructions done unattended")
    parser.add_argument("--confirm-hazardous", action="store_true", help="confirm hazardous commands unattended")
    parser.add_argument(
        "--approver",
        metavar="USER",
        help="a second operator who approves the commands that need approval (the robot side's critical "
        "commanding), checked against their account: their password from $CARETAKER_APPROVER_PASSWORD, or asked "
        "at the start; without it such a command waits for a second operator at this terminal. With --onboard "
        "the approvals go up in the unit, signed with it",
    )
    parser.add_argument(
        "--rehearsal",
        action="store_true",
        help="run a draft (or a procedure changed since its release) as a rehearsal, on a simulator only",
    )
    parser.add_argument(
        "--deployment",
        action="append",
        default=[],
        type=Path,
        metavar="PATH",
        help="the deployment of the robot side the binding reaches, or a folder of deployments (a simulator? "
        "which commands need approval?), when it is neither shipped nor beside the binding",
    )
    parser.add_argument(
        "--break", action="append", default=[], dest="breakpoints", metavar="N", help="breakpoint at instruction N"
    )
    parser.add_argument("--resume", metavar="RUN", help="continue an interrupted run from the audit log")
    parser.add_argument(
        "--proposal",
        type=int,
        metavar="ID",
        help="start the run of an agent's proposal you accepted on a console: its values go with the run, whose "
        "record names the proposal and the agent (a console's acceptance starts this itself)",
    )
    parser.add_argument(
        "--onboard",
        action="store_true",
        help="uplink the procedure to the habitat's onboard executive and supervise it from here "
        "(docs/deployment.md, Onboard runs)",
    )
    parser.add_argument(
        "--attach",
        metavar="RUN",
        help="supervise onboard run RUN, already on the habitat, from here (its supervisor stopped): catch its "
        "record up from the last event stored here and go on (docs/deployment.md, Onboard runs)",
    )
    parser.add_argument(
        "--via-supervisor",
        action="store_true",
        help="with --onboard: hand the unit to the supervisor that keeps the habitat's session open "
        "(caretaker supervise --binding FILE, on this --db) instead of opening one, and follow the run from the "
        "database (docs/deployment.md, Onboard runs)",
    )
    parser.add_argument(
        "--no-follow",
        action="store_true",
        help="with --via-supervisor: end once the habitat took the unit; its supervisor keeps the record and hosts "
        "the run for the consoles",
    )
    parser.add_argument(
        "--supervisor-within",
        type=float,
        default=SUPERVISOR_WITHIN_S,
        metavar="S",
        help=f"with --via-supervisor: how long a supervisor may take to take the run (default "
        f"{SUPERVISOR_WITHIN_S:.0f} s); past it the run is withdrawn, nothing went up, and the runner says so",
    )
    parser.add_argument(
        "--unit-lifetime",
        type=float,
        default=UNIT_LIFETIME_S,
        metavar="S",
        help="with --onboard: how long the unit may take to reach the habitat and start, beyond what the link's "
        f"light time needs to connect and uplink (default {UNIT_LIFETIME_S:.0f} s); past it the habitat refuses "
        "it as expired",
    )
    parser.add_argument(
        "--at-consoles",
        action="store_true",
        help="with --onboard: operators answer at the consoles (the run is hosted for them), so a hold waits for "
        "them; without it, a supervising terminal with nobody at it stops the run at a hold",
    )
    parser.add_argument(
        "--in-flight",
        choices=("resend", "skip"),
        help="on --resume of a log from before command keys: what to do with a command in flight at the crash "
        "(a keyed command is sent again with its key by itself: the habitat answers its outcome)",
    )
    parser.add_argument(
        "--take-over",
        metavar="REASON",
        help="take control of the robot from the run that holds it (logged in both runs)",
    )
    sysrep_option(parser)
    raw_option(parser)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")

    values: dict[str, str] = {}
    for item in args.set:
        name, sep, value = item.partition("=")
        if not sep or not name:
            parser.error(f"--set expects NAME=VALUE, got {item!r}")
        values[name] = value
    try:
        audit = AuditLog(args.db)
    except (AuditSchemaError, AuditLogUnavailable) as exc:
        print(f"caretaker run: {exc}", file=sys.stderr)
        return 2
    try:
        return _run(args, parser, audit, values)
    finally:
        audit.close()


def _run(args: argparse.Namespace, parser: argparse.ArgumentParser, audit: AuditLog, values: dict[str, str]) -> int:
    if args.attach:
        if args.procedure or args.onboard or args.resume:
            parser.error("--attach RUN supervises a run already on the habitat: no PROC, --onboard or --resume")
        from caretaker.onboard_commands import attach

        return attach(args, audit)
    if args.via_supervisor and not args.onboard:
        parser.error("--via-supervisor hands an onboard unit to a supervisor: give --onboard")
    if args.no_follow and not args.via_supervisor:
        parser.error("--no-follow leaves the run to its supervisor: give --onboard --via-supervisor")
    if (args.from_step or args.to_step) and args.resume:
        parser.error("--from and --to start a new run of part of a procedure: not with --resume")
    if args.proposal is not None and args.resume:
        parser.error("--proposal starts the run an operator accepted: not with --resume")
    try:
        events = audit.events(args.resume) if args.resume else []
    except EventDataError as exc:  # a stored event that does not fit its kind: edited, or not a run's own
        print(f"caretaker run: cannot resume: {exc}; {audit.verify(args.resume).describe()}", file=sys.stderr)
        return 2
    if args.resume and not events:
        print(f"caretaker run: no run {args.resume!r} in {args.db}", file=sys.stderr)
        return 2
    start = run_start(events)
    path = args.procedure or (start.path if start else None)
    if not path:
        parser.error("give PROC (or --resume RUN)")
    try:
        sysreps = load_sysreps(args.sysrep_dir)
    except SysRepError as exc:
        print(exc, file=sys.stderr)
        return 2
    try:
        side = robot_side_for(Path(args.binding), deployments=args.deployment)
    except DataFileError as exc:
        print(f"caretaker run: the deployment serving {args.binding} cannot be used: {exc}", file=sys.stderr)
        return 2
    try:
        setup = _setup(args, path, side, sysreps, audit, events)
    except ProcedureError as exc:
        for problem in exc.problems:
            print(problem, file=sys.stderr)
        print(f"caretaker run: {path} has errors; it does not start", file=sys.stderr)
        return 1
    except ReleaseRefused as exc:
        print(f"caretaker run: {exc}{'' if args.rehearsal else ' (--rehearsal)'}", file=sys.stderr)
        return 2
    checked = setup.checked
    procedure = checked.procedure
    if events:
        refusal = resume_refusal(checked, path, events[0].data, side)
        if refusal is not None:
            print(f"caretaker run: {refusal}", file=sys.stderr)
            return 2
    try:
        approver = _approver(args, checked, side)
    except ValueError as exc:
        print(f"caretaker run: {exc}", file=sys.stderr)
        return 2
    if args.onboard:
        from caretaker.onboard_commands import run_onboard

        try:
            proposal = proposal_taken(args.proposal, audit, args.user, setup, values)
        except ProposalNotRunnable as exc:
            print(f"caretaker run: {exc}", file=sys.stderr)
            return 2
        return run_onboard(args, setup, audit, values, approver, proposal)
    try:
        gateway = open_gateway(args.binding, rosbridge_url=args.rosbridge)
    except Exception as exc:  # the host's errors (bad binding, no jar, no rosbridge) end the run here
        print(f"caretaker run: cannot open binding {args.binding}: {exc}", file=sys.stderr)
        return 2
    control = RobotControl(args.db)
    try:
        unserved = setup.unserved(gateway)
        if unserved is not None:
            print(f"caretaker run: {unserved}", file=sys.stderr)
            return 2
        terminal = TerminalLines()
        printer = ProgressPrinter(procedure, terminal, Wording(checked.sysreps, args.raw))
        left_behind = LeftBehind(terminal)
        try:
            if args.resume:
                executive = setup.resumed(
                    gateway,
                    audit,
                    events,
                    args.user,
                    mode=args.mode,
                    control=control,
                    take_over=args.take_over,
                    listeners=(printer, left_behind),  # the resumed run's own events, not the replay
                )
            else:
                executive = setup.executive(gateway, audit, mode=args.mode or Mode.MANUAL, control=control)
                executive.add_listener(printer)
                executive.add_listener(left_behind)
                for number in args.breakpoints:  # before the start: automation must not pass them first
                    executive.set_breakpoint(args.user, number)
                proposal = proposal_taken(args.proposal, audit, args.user, setup, values)
                try:
                    executive.start(
                        args.user,
                        take_over=args.take_over,
                        section=section_of(args, checked, values),
                        proposal=proposal,
                    )
                except (OperatorActionError, SectionError) as exc:
                    if proposal is not None:
                        ProposalStore(audit.engine).reopen(proposal.id, args.user, str(exc))
                    raise
        except ProposalNotRunnable as exc:
            print(f"caretaker run: {exc}", file=sys.stderr)
            return 2
        except RobotControlled as exc:
            print(f"caretaker run: {exc} (--take-over REASON)", file=sys.stderr)
            return 2
        except (OperatorActionError, SectionError) as exc:
            print(f"caretaker run: {exc}", file=sys.stderr)
            return 2
        if args.resume:
            for number in args.breakpoints:
                executive.set_breakpoint(args.user, number)
        terminal.say(f"READY run {executive.run_id}")
        answers = Unattended(values, args.confirm_manual, args.confirm_hazardous, args.in_flight, approver)
        console = OperatorConsole(
            executive,
            args.user,
            answers,
            interactive=sys.stdin.isatty(),
            out=terminal,
            second_operator=lambda user, password: _second_operator(args, user, password),
        )
        previous = signal.signal(signal.SIGINT, lambda _signum, _frame: console.interrupt())
        try:
            final = console.run()
        finally:
            signal.signal(signal.SIGINT, previous)
        executive.join(30)
        if final.error:
            print(f"caretaker run: recording failed, run stopped: {final.error}", file=sys.stderr)
        terminal.say(
            f"RESULT {final.status.value} run {executive.run_id} (report: caretaker report {executive.run_id}"
            f"{'' if args.db == DEFAULT_DB else ' --db ' + args.db})"
        )
        return 0 if final.status is RunStatus.COMPLETED else 1
    finally:
        gateway.close()
        control.close()


def _setup(
    args: argparse.Namespace,
    path: str,
    side: RobotSide,
    sysreps: dict[str, SysRep],
    audit: AuditLog,
    events: list[Event],
) -> RunSetup:
    """The run's set-up: a recorded run's going on (``events``), or a new run's, its version
    decided by the release history (ReleaseRefused says why it may not run)."""
    if events:
        return RunSetup.resuming(path, side, sysreps, events)
    return RunSetup.prepare(
        path,
        side,
        sysreps,
        version=lambda checked, side: version_for_run(
            ReleaseStore(audit.engine), checked, path, side, rehearsal=args.rehearsal
        ),
    )


def _second_operator(args: argparse.Namespace, user: str, password: str) -> str:
    """The user id of a second operator whose password checks out in the ground database, who is
    not the run's user; ValueError says why not."""
    from console.accounts import AccountStore

    if user == args.user:
        raise ValueError(f"{user} runs this: a second operator must approve, not {user}")
    store = AccountStore(args.db)
    try:
        account = store.verify(user, password)
    finally:
        store.close()
    if account is None:
        raise ValueError(f"{user}: unknown user or wrong password (accounts of {args.db})")
    if not account.may_act:
        raise ValueError(f"{user} is an {account.role.value}: only an operator approves commands")
    return account.user


def _approver(args: argparse.Namespace, checked: CheckedProcedure, side: RobotSide) -> str | None:
    """``--approver``, checked against their account before the run starts (ValueError says why not)."""
    if args.approver is None:
        return None
    password = os.environ.get(APPROVER_PASSWORD_ENV)
    if not password and sys.stdin.isatty():
        password = getpass.getpass(f"{args.approver}'s password (approving for {args.user}): ")
    if not password:
        raise ValueError(f"--approver {args.approver}: give their password in ${APPROVER_PASSWORD_ENV}")
    approver = _second_operator(args, args.approver, password)
    log.info("%s approves the commands that need approval (%s)", approver, side.approvals.describe())
    return approver


def report_main(argv: list[str] | None = None) -> int:
    """``caretaker report RUN``: write the after-action report (HTML and Markdown); ``--verify`` checks the chain.

    Exit codes: 0 written (or verified intact); 1 the run's hash chain is broken; 2 no such run.
    """
    from pride.report import write_report

    parser = argparse.ArgumentParser(prog="caretaker report", description="write the after-action report of a run")
    parser.add_argument("run", metavar="RUN", nargs="?", help="run id (omit with --list or --agent)")
    parser.add_argument("--db", default=DEFAULT_DB, metavar="URL")
    parser.add_argument("--out", default="var/reports", metavar="DIR", help="where to write RUN.html and RUN.md")
    parser.add_argument("--list", action="store_true", help="list the runs in the audit log")
    parser.add_argument(
        "--verify", action="store_true", help="only check the run's hash chain and name the first event that breaks it"
    )
    sysrep_option(parser)
    raw_option(parser)
    parser.add_argument(
        "--agent",
        metavar="NAME",
        help="list what the agent NAME asked and was answered or refused, and check its chain",
    )
    parser.add_argument(
        "--since",
        metavar="WHEN",
        type=_since,
        help="with --agent: from this UTC time (2026-12-06T20:00) or this long ago (2h, 7d)",
    )
    args = parser.parse_args(argv)
    if args.verify and not args.run:
        parser.error("--verify needs RUN")
    if args.since is not None and args.agent is None:
        parser.error("--since needs --agent")
    try:
        audit = AuditLog(args.db)
    except (AuditSchemaError, AuditLogUnavailable) as exc:
        print(f"caretaker report: {exc}", file=sys.stderr)
        return 2
    try:
        if args.agent is not None:
            return _agent_report(audit, args.agent, args.since)
        if args.list or not args.run:
            for run_id, started, procedure_id in audit.runs():
                print(f"{run_id}  {started:%Y-%m-%d %H:%M:%S}Z  {procedure_id}")
            return 0
        try:
            events = audit.events(args.run)
        except EventDataError as exc:  # a stored event that does not fit its kind: its chain says more
            print(f"caretaker report: {exc}; {audit.verify(args.run).describe()}", file=sys.stderr)
            return 1
        if not events or events[0].kind is not EventKind.RUN_STARTED:
            print(f"caretaker report: no run {args.run!r} in {args.db}", file=sys.stderr)
            return 2
        check = audit.verify(args.run)
        if args.verify:
            print(check.describe(), file=sys.stdout if check.ok else sys.stderr)
            return 0 if check.ok else 1
        try:
            sysreps = load_sysreps(args.sysrep_dir)  # the report names commands and telemetry by their labels
        except SysRepError as exc:
            print(exc, file=sys.stderr)
            return 2
        if not check.ok:
            print(f"caretaker report: WARNING {check.describe()}", file=sys.stderr)
        wording = Wording(sysreps, args.raw)
        html_path, md_path = write_report(events, Path(args.out), integrity=check.describe(), wording=wording)
        print(html_path)
        print(md_path)
        return 0 if check.ok else 1
    finally:
        audit.close()


def _since(text: str) -> datetime:
    """``--since``: an ISO time (UTC unless it says otherwise) or a duration back from now."""
    try:
        return datetime.now(UTC) - parse_duration(text)
    except TokenError:
        pass
    try:
        moment = datetime.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is neither a time (2026-12-06T20:00) nor a duration back from now (2h, 7d)"
        ) from None
    return moment if moment.tzinfo else moment.replace(tzinfo=UTC)


def _agent_report(audit: AuditLog, agent: str, since: datetime | None) -> int:
    """``caretaker report --agent NAME``: its calls, one per line, then its chain. Exit 0 intact, 1 broken, 2 none."""
    from agent.agent_audit import AgentRecords, record_line
    from records.audit_chain import verify_chain

    stored = AgentRecords(audit.engine).records(agent)
    if not stored:
        print(f"caretaker report: agent {agent!r} made no calls recorded in this database", file=sys.stderr)
        return 2
    for record in stored:
        if since is None or record.time >= since:
            print(record_line(record))
    check = verify_chain(agent, stored)
    if check.ok:
        print(f"agent {agent}: chain of {check.events} records intact; head {check.head}")
        return 0
    print(f"caretaker report: agent {agent}: {check.problem}", file=sys.stderr)
    return 1


def db_main(argv: list[str] | None = None) -> int:
    """``caretaker db upgrade|status --db URL``: the audit log's schema revision (docs/ground-segment.md)."""
    parser = argparse.ArgumentParser(prog="caretaker db", description="create or upgrade the audit log's schema")
    parser.add_argument(
        "action",
        choices=("upgrade", "status"),
        help="upgrade: bring the schema to this Caretaker's revision (as the database owner); "
        "status: print the revision",
    )
    parser.add_argument("--db", default=DEFAULT_DB, metavar="URL", help=f"audit log URL (default {DEFAULT_DB})")
    args = parser.parse_args(argv)
    try:
        audit = AuditLog(args.db, upgrade=args.action == "upgrade")  # upgrades a schema behind, if this role may
    except (AuditSchemaError, AuditLogUnavailable) as exc:
        print(f"caretaker db: {exc}", file=sys.stderr)
        return 1
    try:
        print(f"{audit.location}: schema at revision {audit.schema_revision()} (this Caretaker: {head_revision()})")
        return 0
    finally:
        audit.close()
