"""``caretaker link``: run the link emulator between a ground client and the habitat's bridge.

So a ground team can rehearse a procedure with the delay, loss and outages it will fly with::

    caretaker link --listen 127.0.0.1:9091 --to 127.0.0.1:9090 --delay 1.3 --loss 0.05 \\
        --down-kbps 64 --up-kbps 16 --seed 7 --outage hold:30@40 --control /tmp/link.sock

Prints ``READY link HOST:PORT -> HOST:PORT (...)`` once it listens. docs/link.md has the model.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import sys
from pathlib import Path
from typing import NoReturn

from .control import ControlServer
from .model import LinkConfig, LinkOptionError, parse_address, parse_outage
from .relay import LinkEmulator

__all__ = ["main"]

PROG = "caretaker link"


class _Parser(argparse.ArgumentParser):
    """argparse with the one-line errors of the rest of the command."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{PROG}: {message} (see {PROG} --help)\n")


def _fraction(text: str) -> float:
    """A loss as a fraction (0.05) or a percentage (5%)."""
    try:
        return float(text[:-1]) / 100 if text.endswith("%") else float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a fraction (0.05) or a percentage (5%)") from None


def _parser() -> _Parser:
    parser = _Parser(prog=PROG, description="TCP relay that emulates a long, lossy ground-habitat link (docs/link.md)")
    parser.add_argument(
        "--listen",
        default="127.0.0.1:9091",
        metavar="HOST:PORT",
        help="where ground clients connect; port 0 picks one (default 127.0.0.1:9091)",
    )
    parser.add_argument(
        "--to",
        default="127.0.0.1:9090",
        metavar="HOST:PORT",
        help="the habitat side to connect to, e.g. its rosbridge (default 127.0.0.1:9090)",
    )
    parser.add_argument(
        "--delay",
        type=float,
        default=0.0,
        metavar="S",
        help="least one-way delay in seconds, each direction (Gateway: 1.3)",
    )
    parser.add_argument(
        "--jitter",
        type=float,
        default=0.0,
        metavar="S",
        help="up to this many seconds more per segment, order kept (default 0)",
    )
    parser.add_argument(
        "--loss",
        type=_fraction,
        default=0.0,
        metavar="P",
        help="segment loss, each direction, as 0.05 or 5%%; seen as TCP retransmission stalls",
    )
    parser.add_argument("--up-kbps", type=float, metavar="KBPS", help="uplink (ground→habitat) bit rate")
    parser.add_argument("--down-kbps", type=float, metavar="KBPS", help="downlink (habitat→ground) bit rate")
    parser.add_argument("--seed", type=int, default=0, help="seed of jitter and loss (same seed, same pattern)")
    parser.add_argument(
        "--outage",
        action="append",
        default=[],
        metavar="KIND:S@T",
        help="hold:S@T holds all traffic S seconds from T s after ready; reset:S@T resets "
        "every connection and refuses new ones for S seconds (repeatable)",
    )
    parser.add_argument(
        "--control",
        type=Path,
        metavar="PATH",
        help="Unix socket for run-time outages and stats (one JSON line per request)",
    )
    parser.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    return parser


def _config(args: argparse.Namespace) -> tuple[LinkConfig, tuple[str, int], tuple[str, int]]:
    """The link the options describe.

    Raises:
        LinkOptionError: an option is out of range or malformed.
    """
    listen = parse_address("--listen", args.listen)
    target = parse_address("--to", args.to)
    outages = tuple(parse_outage(spec) for spec in args.outage)
    try:
        config = LinkConfig.symmetric(
            delay=args.delay,
            jitter=args.jitter,
            loss=args.loss,
            up_kbps=args.up_kbps,
            down_kbps=args.down_kbps,
            seed=args.seed,
            outages=outages,
        )
    except LinkOptionError as exc:
        option = {"kbps": "--up-kbps/--down-kbps"}.get(exc.option, f"--{exc.option}")
        raise LinkOptionError(option, exc.value, exc.expected) from None
    return config, listen, target


async def _run(config: LinkConfig, listen: tuple[str, int], target: tuple[str, int], control_path: Path | None) -> int:
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(signum, stop.set)
    link = LinkEmulator(config, listen=listen, target=target)
    control = ControlServer(link, control_path) if control_path else None
    try:
        await link.start()
        if control is not None:
            await control.start()
    except OSError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        await link.close()
        return 1
    host, port = link.address
    extra = f" control {control_path}" if control_path else ""
    print(f"READY link {host}:{port} -> {target[0]}:{target[1]} ({config.describe()}){extra}", flush=True)
    try:
        await stop.wait()
    finally:
        if control is not None:
            await control.close()
        await link.close()
    stats = link.stats()
    logging.getLogger("caretaker.link").info(
        "stopped: %d bytes up, %d bytes down, %d connection(s)",
        stats.up_bytes,
        stats.down_bytes,
        len(stats.connections),
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the link until Ctrl-C or SIGTERM; 2 for bad options, 1 if it cannot listen."""
    args = _parser().parse_args(argv)
    try:
        config, listen, target = _config(args)
    except LinkOptionError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 2
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    return asyncio.run(_run(config, listen, target, args.control))
