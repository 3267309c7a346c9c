"""``caretaker onboard``: the habitat's onboard executive, served to the ground through rosbridge.

A part of ``caretaker up`` (when the deployment has ``onboard:``). It is a rosbridge client of the
habitat's own bridge, logged in with the link's secret, and advertises its services
(``caretaker_onboard_msgs``) that the ground calls across the link like any other:

- ``/caretaker_onboard/uplink`` (``Uplink``): take a signed unit, answer with its hash;
- ``/caretaker_onboard/events`` (``RunEvents``): a run's events above a number, waiting for the next;
- ``/caretaker_onboard/follow`` (``RunEvents``): the same for a ground that keeps several requests
  waiting, so that one is here whenever an event happens: each event goes down once (:mod:`.followers`);
- ``/caretaker_onboard/action`` (``OperatorAction``): an operator's keyed action (Halt first);
- ``/caretaker_onboard/status`` (``HabitatStatus``): the active run, units answered, refusals counted;
- ``/caretaker_onboard/unit`` (``RunUnit``): the unit a run started from, for a ground that attaches.

Refused units and actions are security events: printed as ``SECURITY ...`` lines whatever the log
level, which ``caretaker up`` shows even when it does not echo its parts.

It opens no port: the bridge stays the one service the link reaches. Each request runs on a thread
of its own (an uplink starts a JVM, a request for events waits for the next one), so a Halt is
never queued behind them.
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import dataclasses
import json
import logging
import signal
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from datafile import DataFileError
from pride.run_setup import load_sysreps
from procedure_language.binding import read_binding
from procedure_language.sysrep import SysRepError
from rosbridge_wire.client import RosbridgeClient

from .habitat_runs import SECURITY_LOG, EventsAnswer, HabitatRuns
from .unit import ACTION_SERVICE, EVENTS_SERVICE, FOLLOW_SERVICE, STATUS_SERVICE, UNIT_SERVICE, UPLINK_SERVICE

__all__ = ["events_values", "main"]

log = logging.getLogger("caretaker.onboard")

DEFAULT_SYSREP_DIR = Path(__file__).resolve().parents[2] / "sysrep"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="caretaker onboard", description="the habitat's onboard executive")
    parser.add_argument(
        "--bridge", required=True, metavar="URL", help="the habitat's rosbridge as this host reaches it"
    )
    parser.add_argument(
        "--binding",
        action="append",
        required=True,
        metavar="FILE",
        help="a binding units may name (repeatable); the first gives the trust (CA, secret) for --bridge",
    )
    parser.add_argument("--state-dir", required=True, type=Path, help="where units, events and actions are kept")
    parser.add_argument("--sysrep-dir", action="append", metavar="DIR", help="SysReps units are linted against")
    parser.add_argument("--log-level", default="INFO")
    return parser.parse_args(argv)


async def serve(args: argparse.Namespace) -> int:
    bindings = {Path(path).name: Path(path).resolve() for path in args.binding}
    first = read_binding(args.binding[0])
    endpoint = dataclasses.replace(first.endpoint(args.bridge), one_way_delay=0.0)  # this host: no link between
    if endpoint.secret is None:
        print(f"caretaker onboard: {args.binding[0]} gives no secret_file: units are signed with it", file=sys.stderr)
        return 2
    sysreps = load_sysreps(args.sysrep_dir or [DEFAULT_SYSREP_DIR])  # a duplicate id is refused (main)
    runs = HabitatRuns(
        args.state_dir, secret=endpoint.secret, bindings=bindings, sysreps=sysreps, rosbridge_url=args.bridge
    )
    # one thread per request in flight: a Halt must not wait behind an uplink or a long poll
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=16, thread_name_prefix="onboard-request")
    loop = asyncio.get_running_loop()

    def threaded(function: Any) -> Any:
        async def handler(request: Mapping[str, Any]) -> Mapping[str, Any]:
            answer = await loop.run_in_executor(pool, function, request)
            return dataclasses.asdict(answer)

        return handler

    client = RosbridgeClient(endpoint, name="caretaker-onboard")
    client.advertise_service(
        UPLINK_SERVICE,
        "caretaker_onboard_msgs/srv/Uplink",
        threaded(lambda r: runs.uplink(str(r.get("unit_json", "")), str(r.get("signature", "")))),
    )
    client.advertise_service(
        EVENTS_SERVICE,
        "caretaker_onboard_msgs/srv/RunEvents",
        threaded(lambda r: events_values(runs.events, r)),
    )
    client.advertise_service(
        FOLLOW_SERVICE,
        "caretaker_onboard_msgs/srv/RunEvents",
        threaded(lambda r: events_values(runs.follow, r)),
    )
    client.advertise_service(
        ACTION_SERVICE,
        "caretaker_onboard_msgs/srv/OperatorAction",
        threaded(lambda r: runs.act(str(r.get("action_json", "")), str(r.get("signature", "")))),
    )
    client.advertise_service(
        STATUS_SERVICE, "caretaker_onboard_msgs/srv/HabitatStatus", threaded(lambda r: runs.status())
    )
    client.advertise_service(
        UNIT_SERVICE, "caretaker_onboard_msgs/srv/RunUnit", threaded(lambda r: runs.unit_of(str(r.get("run_id", ""))))
    )
    stop = asyncio.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(signum, stop.set)
    try:
        # resumed before the services are served: the ground must never hear "interrupted" of a
        # run that is about to go on
        for run_id in await loop.run_in_executor(pool, runs.resume_interrupted):
            print(f"RESUMED onboard run {run_id}", flush=True)
        client.start()
        await client.ready.wait()
        print(f"READY onboard {args.bridge} ({len(bindings)} binding{'s' if len(bindings) != 1 else ''})", flush=True)
        await stop.wait()
    finally:
        await client.close()
        await loop.run_in_executor(None, runs.close)
        pool.shutdown(wait=False, cancel_futures=True)
    return 0


@dataclasses.dataclass(frozen=True)
class _EventsValues:
    events_json: str
    head_seq: int
    status: str
    habitat_time: str
    waiting: str
    message: str
    snapshot_json: str


def events_values(
    answer_of: Callable[[str, int, float, int], EventsAnswer], request: Mapping[str, Any]
) -> _EventsValues:
    """RunEvents' response (``answer_of``: :meth:`HabitatRuns.events` or ``follow``): the events as one
    JSON text (the srv carries strings)."""

    def number(name: str, kind: type) -> Any:
        value = request.get(name, 0)
        return value if isinstance(value, (int, float)) and not isinstance(value, bool) else kind(0)

    answer = answer_of(
        str(request.get("run_id", "")),
        int(number("after_seq", int)),
        float(number("wait_s", float)),
        int(number("max_events", int)),
    )
    return _EventsValues(
        json.dumps(answer.events),
        answer.head_seq,
        answer.status,
        answer.habitat_time,
        answer.waiting,
        answer.message,
        json.dumps(answer.snapshot, default=str) if answer.snapshot is not None else "",
    )


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    # security events reach the habitat's log at any level, on a line of their own kind
    printer = logging.StreamHandler(sys.stdout)
    printer.setFormatter(logging.Formatter("SECURITY %(asctime)s %(message)s"))
    security = logging.getLogger(SECURITY_LOG)
    security.addHandler(printer)
    security.setLevel(logging.INFO)
    security.propagate = False
    try:
        return asyncio.run(serve(args))
    except (DataFileError, SysRepError, OSError) as exc:
        print(f"caretaker onboard: {exc}", file=sys.stderr)
        return 2
