"""``caretaker ledger``: run the habitat's command ledger node (see :mod:`bridge.ledger.node`)."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import rclpy
from rclpy.executors import MultiThreadedExecutor

from ros_process import spinning

from .node import LedgerNode
from .store import LedgerStore, LedgerStoreError

__all__ = ["STATE_FILE", "main"]

STATE_FILE = "command_ledger.sqlite"


def main(argv: list[str] | None = None) -> int:
    """Serve the ledger until Ctrl-C; prints ``READY ledger <epoch> <state file>`` once it serves."""
    parser = argparse.ArgumentParser(prog="caretaker ledger", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--state-dir",
        type=Path,
        required=True,
        help=f"folder of the ledger's memory ({STATE_FILE}); keep it across restarts",
    )
    parser.add_argument(
        "--default-timeout",
        type=float,
        default=10.0,
        help="s to wait for a service's answer when a request gives no timeout (default 10)",
    )
    parser.add_argument(
        "--retain-hours",
        type=float,
        default=168.0,
        help="keep finished records this long (default a week); pruning starts a new epoch",
    )
    parser.add_argument(
        "--threads", type=int, default=16, help="executor threads: calls waiting at once, plus answers (default 16)"
    )
    parser.add_argument("--log-level", default="INFO")
    args, ros_args = parser.parse_known_args(argv)
    if args.default_timeout <= 0 or args.retain_hours <= 0 or args.threads < 2:
        parser.error("--default-timeout and --retain-hours must be positive, --threads at least 2")
    logging.basicConfig(level=args.log_level.upper(), format="%(levelname)s %(name)s: %(message)s")
    try:
        store = LedgerStore(args.state_dir / STATE_FILE, retain_s=args.retain_hours * 3600.0)
    except LedgerStoreError as exc:
        print(f"caretaker ledger: {exc}", file=sys.stderr)
        return 2
    if store.interrupted:
        logging.getLogger(__name__).warning(
            "%d calls were in progress when the ledger stopped: now UNKNOWN", store.interrupted
        )
    rclpy.init(args=ros_args)
    executor = MultiThreadedExecutor(num_threads=args.threads)
    try:
        with spinning(executor) as nodes:
            node = LedgerNode(store, default_timeout=args.default_timeout)
            nodes.append(node)
            executor.add_node(node)
            print(f"READY ledger {store.epoch} {store.path}", flush=True)
            executor.spin()
    finally:
        store.close()
    return 0
