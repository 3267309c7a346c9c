"""``caretaker serve``: the operator web view on uvicorn, bound to loopback unless told otherwise.

Prints ``READY serve http://HOST:PORT`` once it accepts connections (``--port 0`` picks a free
port and the line names it), so launchers and tests wait on that line, not on a sleep.
"""

from __future__ import annotations

import argparse
import logging
import socket
import sys
from pathlib import Path

import uvicorn

from pride.audit_log import DEFAULT_DB, AuditLog
from pride.web.accounts import EXAMPLE_ACCOUNTS, AccountsError, load_accounts
from pride.web.app import build_app
from pride.web.reports import report_writer
from pride.web.run_board import CameraSettings, Catalog, RunBoard
from pride.web.sign_in import SignIns

__all__ = ["main"]

log = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[3]


class _Server(uvicorn.Server):
    """uvicorn, announcing readiness after its sockets accept connections."""

    def __init__(self, config: uvicorn.Config, url: str) -> None:
        super().__init__(config)
        self.url = url

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        await super().startup(sockets=sockets)
        if not self.should_exit:
            print(f"READY serve {self.url}", flush=True)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="caretaker serve", description="Serve the operator web view.")
    parser.add_argument("--address", default="127.0.0.1", help="address to bind (default: loopback only)")
    parser.add_argument("--port", type=int, default=8080, help="TCP port (0 = any free port; default 8080)")
    parser.add_argument("--accounts", type=Path, default=EXAMPLE_ACCOUNTS,
                        help=f"accounts YAML with user ids and roles (default: {EXAMPLE_ACCOUNTS.name})")
    parser.add_argument("--db", default=DEFAULT_DB, help=f"audit log SQLAlchemy URL (default: {DEFAULT_DB})")
    parser.add_argument("--procedures", type=Path, default=REPO / "procedures", help="directory of procedure XML files")
    parser.add_argument("--bindings", type=Path, default=REPO / "sysrep" / "bindings", help="directory of binding files")
    parser.add_argument("--sysreps", type=Path, default=REPO / "sysrep", help="directory of SysRep YAML files")
    parser.add_argument("--rosbridge", metavar="URL", help="override the bindings' rosbridge URL (e.g. ws://127.0.0.1:9091)")
    parser.add_argument("--camera", metavar="NAME",
                        help="camera to show while the robot moves (e.g. ee_camera, scene), when the binding serves the camera SysRep")
    parser.add_argument("--camera-period", type=float, default=0.5, metavar="S", help="seconds between live captures (default 0.5)")
    parser.add_argument("--reports", type=Path, default=REPO / "var" / "reports", help="where after-action reports are written")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Serve until interrupted; returns the exit code."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        accounts = load_accounts(args.accounts)
    except AccountsError as exc:
        print(f"caretaker serve: {exc}", file=sys.stderr)
        return 2
    for directory in (args.procedures, args.sysreps):
        if not directory.is_dir():
            print(f"caretaker serve: {directory} is not a directory", file=sys.stderr)
            return 2
    if args.address not in ("127.0.0.1", "localhost", "::1"):
        log.warning("serving on %s: the web view is reachable beyond this machine", args.address)
    audit_log = AuditLog(args.db)
    catalog = Catalog(args.procedures.resolve(), args.bindings.resolve(), args.sysreps.resolve())
    board = RunBoard(catalog, audit_log, CameraSettings(args.camera, args.camera_period), rosbridge_url=args.rosbridge)
    app = build_app(board, SignIns(accounts), report_writer=report_writer(audit_log, args.reports))
    family = socket.AF_INET6 if ":" in args.address else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((args.address, args.port))
    except OSError as exc:
        print(f"caretaker serve: cannot bind {args.address}:{args.port}: {exc.strerror}", file=sys.stderr)
        return 2
    host, port = sock.getsockname()[:2]
    url = f"http://[{host}]:{port}" if family == socket.AF_INET6 else f"http://{host}:{port}"
    server = _Server(uvicorn.Config(app, log_level="warning", lifespan="on", ws="websockets-sansio"), url)
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        pass
    finally:
        audit_log.close()
    return 0
