"""``caretaker demo DEPLOYMENT``: stack up, the deployment's procedure autonomously, world checks, report.

The procedure runs in its own process (``caretaker run``, with its own JVM), exactly as an
operator would start it, with the answers the deployment's ``demo.inputs`` give. A command that
needs a second operator's approval (the IVA unlock: hazardous in the cdra SysRep) waits for it
as on any run: the demo's operator sends it for approval and a second operator account of the
demo's database, :data:`DEMO_APPROVER`, approves it (``caretaker run --confirm-hazardous
--approver``, its password new for each demo, in the runner's environment). The demo then
checks the *world*, not the procedure's word for it — the deployment's ``demo.checks``
(:mod:`caretaker.world_checks`), watched from before the procedure starts: a run that says
COMPLETED while the filter is still in the wrong place is a failed demo.

The audit log and the report go where ``--db`` and ``--reports`` say, else to ``var/`` of the
deployment's home: the checkout for a deployment inside it, the deployment's own folder for one
outside, so a robot kept in a folder of its own never writes into the checkout.
"""

from __future__ import annotations

import argparse
import logging
import secrets
import sys
import time
from pathlib import Path

from caretaker.deployment import Deployment, load_deployment
from caretaker.processes import REPO, ProcessFailed, caretaker
from caretaker.stack import Stack, StackFailed, stack_options
from caretaker.world_checks import watch_world
from console.accounts import AccountStore
from datafile import DataFileError
from pride.approvals import APPROVER_PASSWORD_ENV
from sim import cabin_knobs
from sim.scene import load_scene

__all__ = ["DEMO_APPROVER", "DEMO_USER", "demo_approver", "demo_main", "demo_operator", "demo_home", "run_demo"]

#: The operator account ``--serve`` signs in with (an account of the demo's database like any other).
DEMO_USER = "demo"
#: The second operator who approves the demo run's commands that need approval: nobody is at an
#: unattended run to approve them, and the demo's own operator may not.
DEMO_APPROVER = "demo-approver"


def demo_home(deployment: Deployment) -> Path:
    """The ``var/`` folder the demo's defaults live in: the checkout's for a deployment inside the
    checkout (``make demo`` leaves its log where ``caretaker report`` looks), else one beside the
    deployment file."""
    inside = deployment.path.resolve().is_relative_to(REPO)
    return (REPO if inside else deployment.path.resolve().parent) / "var"


def _run_procedure(
    deployment: Deployment, bridge_url: str, db_url: str, env: dict[str, str], started: float
) -> tuple[str | None, str]:
    """Run the demo's procedure autonomously in its own process; return (run id, final status).

    On a simulator it runs as a rehearsal (the procedure as it is in the checkout, released or
    not); on a real robot only its released version runs."""
    demo = deployment.demo
    assert demo is not None, "main() runs a demo only for a deployment that has one"
    answers = [f"--set={name}={value}" for name, value in demo.inputs.items()]
    approver = {APPROVER_PASSWORD_ENV: demo_approver(db_url)}  # never on the command line
    result: dict[str, str] = {}

    def show(_: str, line: str) -> None:
        print(f"[{time.monotonic() - started:7.1f} s] {line}", flush=True)
        words = line.split()
        if line.startswith("READY run") and len(words) >= 3:
            result["run"] = words[2]
        elif line.startswith("RESULT") and len(words) >= 4:
            result["status"], result["run"] = words[1], words[3]

    runner = caretaker(
        "run",
        str(demo.procedure),
        "--binding",
        str(demo.binding),
        "--rosbridge",
        bridge_url,
        "--auto",
        "--user",
        DEMO_USER,
        "--db",
        db_url,
        "--confirm-manual",
        "--confirm-hazardous",
        "--approver",
        DEMO_APPROVER,
        "--deployment",
        str(deployment.path),
        *(["--rehearsal"] if deployment.simulator else []),
        *answers,
        env={**env, **approver},
        name="run",
        on_line=show,
    )
    runner.proc.wait()
    runner.stop()
    return result.get("run"), result.get("status", f"runner exited with {runner.proc.returncode}")


def demo_operator(db_url: str) -> str:
    """Give the demo operator account (:data:`DEMO_USER`) a new random password, creating the account
    if needed; returns the password, which is shown once and stored only as its hash."""
    return _new_password(db_url, DEMO_USER, "Demo operator")


def demo_approver(db_url: str) -> str:
    """Give the demo's second operator (:data:`DEMO_APPROVER`) a new random password, creating the
    account if needed; returns the password, which only the demo's runner is given."""
    return _new_password(db_url, DEMO_APPROVER, "Demo second operator (approves)")


def _new_password(db_url: str, user: str, name: str) -> str:
    """A new random password for the operator account ``user`` of ``db_url``, made if missing."""
    password = secrets.token_urlsafe(12)
    store = AccountStore(db_url)
    try:
        if store.get(user) is None:
            store.add(user, "operator", password, name=name)
        else:
            store.set_password(user, password)
    finally:
        store.close()
    return password


def _serve(db_url: str, env: dict[str, str]) -> None:
    """Leave the web view running on the demo's audit log until Ctrl-C, with an operator who can sign in."""
    password = demo_operator(db_url)
    web = caretaker("serve", "--db", db_url, env=env, name="serve")
    try:
        print(web.wait_ready(60), "— Ctrl-C to stop", flush=True)
        print(
            f"  sign in as {DEMO_USER} with the password {password}  (shown once: each demo --serve sets a new one)",
            flush=True,
        )
        web.proc.wait()
    except KeyboardInterrupt:
        pass
    except ProcessFailed as exc:
        print(f"caretaker demo: the web view did not start: {exc}")
    finally:
        web.stop()


def run_demo(deployment: Deployment, args: argparse.Namespace) -> int:
    """Bring the stack up, run the procedure, check the world, write the report. Exit 0 only if all hold."""
    demo = deployment.demo
    if demo is None:
        print(f"caretaker demo: {deployment.path} has no demo: section (procedure, binding) to run")
        return 1
    home = demo_home(deployment)
    db_url = args.db or f"sqlite:///{home / 'caretaker.db'}"
    reports = Path(args.reports) if args.reports else home / "reports"
    if not args.db:  # SQLite makes the file, not its folder (the report makes its own)
        home.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    stack = Stack(
        deployment,
        time_scale=args.time_scale,
        bridge_address=args.bridge_address,
        bridge_port=args.bridge_port,
        displace=args.displace,
        cabin=cabin_knobs.given(args),
        echo=args.verbose,
    )
    print(f"Starting the {deployment.name} stack: {', '.join(p.name for p in stack.parts)}", flush=True)
    try:
        stack.start()
    except StackFailed as exc:
        print(f"caretaker demo: {exc}")
        return 1
    try:
        print(
            f"[{time.monotonic() - started:7.1f} s] stack ready ({stack.bridge_url}); "
            f"running {demo.procedure.name} autonomously"
            + (", as a rehearsal on the simulator (released or not)" if deployment.simulator else ""),
            flush=True,
        )
        with watch_world(demo.checks, stack.bridge_url, deployment.namespace, load_scene(deployment.scene)) as world:
            run_id, status = _run_procedure(deployment, stack.bridge_url, db_url, stack.env, started)
            dead = stack.dead_parts()
            if dead:
                print(f"caretaker demo: {', '.join(dead)} died during the run")
                return 1
            if status != "completed" or run_id is None:
                print(f"caretaker demo: the procedure did not complete ({status})")
                return 1
            verdicts = world.judge(db_url, run_id)
        for verdict in verdicts:
            # one write: another thread's log line must not land between a verdict and its newline
            sys.stdout.write(f"  {'verified' if verdict.holds else 'WRONG'}: {verdict.words}\n")
            sys.stdout.flush()
        if not all(verdict.holds for verdict in verdicts):
            print("caretaker demo: the procedure completed but the world is wrong (WRONG above)")
            return 1
        report = caretaker("report", run_id, "--db", db_url, "--out", str(reports), env=stack.env, name="report")
        report.proc.wait()
        report.stop()
        if report.proc.returncode != 0:
            print(f"caretaker demo: the report failed:\n{report.tail()}")
            return 1
        print(f"[{time.monotonic() - started:7.1f} s] {deployment.name} demo complete; run {run_id}")
        print(f"  audit log: {db_url}")
        for line in report.output:
            print(f"  report: {line}")
        if args.serve:
            _serve(db_url, stack.env)
        return 0
    finally:
        stack.stop()


def demo_main(argv: list[str] | None = None) -> int:
    """``caretaker demo DEPLOYMENT``: bring the stack up, run its procedure autonomously, report;
    ``caretaker demo anomaly``: an alarm answered end to end (:mod:`caretaker.anomaly_demo`)."""
    parser = stack_options("caretaker demo")
    parser.description = (
        "Bring a deployment's stack up, run its procedure autonomously, check the world and report. "
        "DEPLOYMENT 'anomaly': the IVA habitat behind a 1.3 s link, a console and the reference agent answer a "
        "CO2 alarm end to end (--reports DIR: where it writes; --db: its ground database)."
    )
    parser.add_argument(
        "--serve",
        action="store_true",
        help=f"leave the web view running after the procedure; sign in as {DEMO_USER} with the password "
        "it prints (a new one each time)",
    )
    parser.add_argument(
        "--db",
        default=None,
        help="audit log SQLAlchemy URL (default: var/caretaker.db of the checkout for a deployment in it, "
        "else beside the deployment file)",
    )
    parser.add_argument(
        "--reports", default=None, metavar="DIR", help="where the report goes (default: var/reports, as for --db)"
    )
    parser.set_defaults(time_scale=0.0)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if args.deployment == "anomaly":
        from caretaker.anomaly_demo import anomaly_demo

        return anomaly_demo(args)
    try:
        deployment = load_deployment(args.deployment)
    except DataFileError as exc:
        print(f"caretaker demo: {exc}", file=sys.stderr)
        return 1
    return run_demo(deployment, args)
