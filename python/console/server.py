"""``caretaker serve``: the operator web view on uvicorn, bound to loopback unless told otherwise.

Prints ``READY serve http://HOST:PORT`` (``https://`` under TLS) once it accepts connections
(``--port 0`` picks a free port and the line names it), so launchers and tests wait on that
line, not on a sleep. Beyond loopback it serves only over TLS (``--certfile``/``--keyfile``):
passwords and session cookies must not cross a network in clear text; ``--insecure`` is for a
network that is encrypted otherwise (a VPN, a TLS-terminating proxy on the same host).
"""

from __future__ import annotations

import argparse
import logging
import re
import socket
import sys
from pathlib import Path

from sqlalchemy.exc import OperationalError

from console.accounts import AccountStore
from console.app import build_app
from console.catalog import CameraSettings, Catalog, catalog_options, per_binding, rosbridge_overrides
from console.listener import Listener, loopback, serve, tls_problem
from console.reports import report_writer
from console.run_board import RunBoard
from console.sign_in import SessionLimits, SignIns
from ground.run_hosts import DEFAULT_LEASE_S
from pride.run_setup import load_sysreps
from procedure_language.sysrep import SysRepError
from records.audit_log import DEFAULT_DB, AuditLog, AuditLogUnavailable
from records.audit_schema import AuditSchemaError

__all__ = ["main"]

log = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[2]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="caretaker serve", description="Serve the operator web view.")
    parser.add_argument("--address", default="127.0.0.1", help="address to bind (default: loopback only)")
    parser.add_argument("--port", type=int, default=8080, help="TCP port (0 = any free port; default 8080)")
    parser.add_argument(
        "--db",
        default=DEFAULT_DB,
        help=f"the ground database: audit log and accounts, a SQLAlchemy URL (default: {DEFAULT_DB})",
    )
    parser.add_argument(
        "--certfile", type=Path, help="TLS certificate chain (PEM); with --keyfile the view is served over https"
    )
    parser.add_argument("--keyfile", type=Path, help="TLS private key (PEM)")
    parser.add_argument(
        "--insecure",
        action="store_true",
        help="allow plain http beyond loopback (only where the network is encrypted otherwise)",
    )
    parser.add_argument(
        "--session-idle",
        type=float,
        default=30.0,
        metavar="MIN",
        help="sign a browser out after this many minutes without use (default 30; an open page is in use)",
    )
    parser.add_argument(
        "--session-max",
        type=float,
        default=12.0,
        metavar="H",
        help="sign everyone out this many hours after they signed in (default 12: a shift)",
    )
    catalog_options(parser)
    parser.add_argument(
        "--deployments",
        type=Path,
        action="append",
        default=[],
        metavar="PATH",
        help="a deployment file, or a folder of them, saying what the robot side of a binding is (a simulator? "
        "which commands need a second operator's approval?) besides the shipped ones and those beside a binding",
    )
    parser.add_argument(
        "--console",
        metavar="NAME",
        help="how other consoles name this one when it hosts a run (default: console HOST:PORT)",
    )
    parser.add_argument(
        "--lease",
        type=float,
        default=DEFAULT_LEASE_S,
        metavar="S",
        help="seconds after which other consoles take a run hosted here for interrupted if this console "
        f"stopped renewing its claim (died, lost the database); default {DEFAULT_LEASE_S:g}",
    )
    parser.add_argument(
        "--via-supervisor",
        action="store_true",
        help='hand onboard starts ("run on the habitat") to the supervisors of their binding '
        "(caretaker supervise on this --db) instead of starting a supervising runner for each",
    )
    parser.add_argument(
        "--camera",
        metavar="[BINDING=]NAME",
        action="append",
        default=[],
        help="camera to show while the robot of the binding file BINDING moves (e.g. iva.yaml=scene, "
        "eva.yaml=ee_camera), or of every binding without BINDING=, when it serves the camera SysRep",
    )
    parser.add_argument(
        "--camera-period", type=float, default=0.5, metavar="S", help="seconds between live captures (default 0.5)"
    )
    parser.add_argument(
        "--reports", type=Path, default=REPO / "var" / "reports", help="where after-action reports are written"
    )
    return parser


#: A camera's name in a robot's scene (``camera/<name>`` frames of the simulation).
_CAMERA_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def main(argv: list[str] | None = None) -> int:
    """Serve until interrupted; returns the exit code."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    args.sysreps = args.sysreps or [REPO / "sysrep"]
    for directory in (args.procedures, *args.sysreps):
        if not directory.is_dir():
            print(f"caretaker serve: {directory} is not a directory", file=sys.stderr)
            return 2
    try:
        load_sysreps(args.sysreps)  # read again at each start: this refuses a bad folder at once
    except SysRepError as exc:
        print(f"caretaker serve: {exc}", file=sys.stderr)
        return 2
    problem = tls_problem(args.address, args.certfile, args.keyfile, args.insecure, "passwords and session cookies")
    if problem is not None:
        print(f"caretaker serve: {problem}", file=sys.stderr)
        return 2
    if args.session_idle <= 0 or args.session_max <= 0:
        print("caretaker serve: --session-idle and --session-max must be positive", file=sys.stderr)
        return 2
    try:
        rosbridge_urls = rosbridge_overrides(args.rosbridge)
        cameras = per_binding(
            "--camera", args.camera, "NAME (a camera of the robot's scene: scene, ee_camera)", _CAMERA_NAME.fullmatch
        )
    except ValueError as exc:
        print(f"caretaker serve: {exc}", file=sys.stderr)
        return 2
    if args.lease < 3:
        print("caretaker serve: --lease must be at least 3 s (claims are renewed every second)", file=sys.stderr)
        return 2
    tls = args.certfile is not None
    if not loopback(args.address):
        log.warning(
            "serving on %s%s: the web view is reachable beyond this machine",
            args.address,
            "" if tls else " WITHOUT TLS",
        )
    try:
        listener = Listener.bind(args.address, args.port, tls=tls)
    except OSError as exc:
        print(f"caretaker serve: cannot bind {args.address}:{args.port}: {exc.strerror}", file=sys.stderr)
        return 2
    try:
        accounts = AccountStore(args.db)
    except (AuditLogUnavailable, AuditSchemaError, OperationalError) as exc:
        print(f"caretaker serve: {exc}", file=sys.stderr)
        return 2
    if not accounts.accounts():
        log.warning(
            "no accounts in %s: nobody can sign in until one is added "
            "(caretaker accounts add USER --role operator --db %s)",
            args.db,
            args.db,
        )
    audit_log = AuditLog(args.db)
    catalog = Catalog(
        args.procedures.resolve(),
        args.bindings.resolve(),
        tuple(path.resolve() for path in args.sysreps),
        tuple(path.resolve() for path in args.deployments),
    )
    board = RunBoard(
        catalog,
        audit_log,
        CameraSettings(cameras, args.camera_period),
        accounts=accounts,
        console=args.console or f"console {socket.gethostname()}:{listener.port}",
        lease=args.lease,
        rosbridge_urls=rosbridge_urls,
        via_supervisor=args.via_supervisor,
    )
    sign_ins = SignIns(accounts, limits=SessionLimits(idle=args.session_idle * 60, absolute=args.session_max * 3600))
    board.feed.subscribe(sign_ins.notice)
    app = build_app(board, sign_ins, report_writer=report_writer(audit_log, args.reports), secure=tls)
    try:
        serve(app, listener, "serve", args.certfile, args.keyfile, lifespan="on", ws="websockets-sansio")
    finally:
        audit_log.close()
        accounts.close()
    return 0
