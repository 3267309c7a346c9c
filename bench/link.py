"""The IVA procedure flown autonomously across an emulated ground–habitat link: time against its bound,
run from the ground and run onboard, side by side.

For each link (none, Gateway's 1.3 s, 1.3 s with 5 % of segments lost, 2.6 s at 64 kbit/s down
and 16 kbit/s up) this brings up the IVA habitat deployment with its link emulated in front of
the bridge (``caretaker up`` with a ``link:`` section: wss:// with a secret, the command ledger),
runs the procedure with ``caretaker run --auto`` through that link with a ground binding stating
the delay, and reports from the run's audit log, the ledger's records and the link's counters:

- ``run``: RUN_STARTED to RUN_COMPLETED in the audit log (the JVM's start and the connection's
  opening are not in it; ``wall`` is the whole ``caretaker run`` process);
- ``habitat``: time the habitat spent on the run's commands (each ledger record's end − start:
  motion, planning, every service), ``motion`` the executions' share of it;
- ``N``: ground decisions that wait for an answer: the commands sent (verifies and waits read
  pushed telemetry and need no round trip);
- ``bound`` = habitat + N × round trip: what the run would take if the ground cost nothing and
  each answer came one round trip after its question; ``ratio`` = run / bound;
- bytes up (ground → habitat) and down that crossed the link, TLS included.

``onboard`` rows run the same procedure with ``caretaker run --onboard`` (the habitat deployment
with ``onboard: true``): N is then the round trips the ground needs at all (the uplink, and the
first and last requests for events), so the bound is habitat + 3 round trips. ``supervised`` rows
run it onboard with the supervisor's session already open: ``caretaker supervise`` has opened its
session to the habitat before ``caretaker run --onboard --via-supervisor`` hands it the unit. Both
onboard modes also report what the ground sees against the habitat's own time:

- ``seen``: from the unit leaving the runner (its ``goes up`` or ``handed`` line) to its ``RESULT``
  line, the ground's clock: the ground has stored the run's last event;
- ``on habitat``: from the unit's arrival on the habitat (its files written there) to
  RUN_COMPLETED, the habitat's clock (one machine here: the same clock);
- ``limit`` = on habitat + 1.5 round trips: a way up, the run, the way down, and half a round
  trip spare.

    .venv/bin/python bench/link.py [--cases 0,1.3,1.3+loss,2.6@64/16|45] [--modes ground,onboard|supervised]
                                   [--time-scale 1] [--robot iva|eva] [--displace SEED]

``--robot eva --displace SEED`` flies the EVA inspection on a displaced Gateway: each hull target
is located from the arm's camera on the habitat, and only the located pose crosses the link.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import random
import sqlite3
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Robot:
    """A robot side to fly across the link: its deployment, the ground's binding and procedure."""

    deployment: Path
    binding: Path  # the ground's; the link, security and address are set per case
    procedure: Path
    run_options: tuple[str, ...]  # caretaker run's: the answers an operator would give at the records, ...


ROBOTS = {
    "iva": Robot(
        REPO / "deployments" / "iva-habitat.yaml",
        REPO / "sysrep" / "bindings" / "iva-ground.yaml",
        REPO / "procedures" / "iva_cdra_filter_replacement.xml",
        ("--set=clean_filter_id=CDRA-F-0012", "--rehearsal"),  # a draft in a fresh database: rehearsed on the simulator
    ),
    # the hull targets located from the arm's camera before each registration (issue 28): with
    # --displace, only the located poses (a few hundred bytes each) cross the link for them
    "eva": Robot(
        REPO / "deployments" / "eva.yaml",
        REPO / "sysrep" / "bindings" / "eva.yaml",
        REPO / "procedures" / "eva_inspection.xml",
        ("--set=damage=false", "--rehearsal"),  # a draft: rehearsed on the simulator
    ),
}


@dataclass(frozen=True)
class Case:
    name: str
    delay: float
    loss: float = 0.0
    down_kbps: float | None = None
    up_kbps: float | None = None
    tls: bool = True


CASES = {
    "0": Case("no delay", 0.0),
    "1.3": Case("1.3 s one way", 1.3),
    "1.3+loss": Case("1.3 s + 5 % loss", 1.3, loss=0.05),
    # ws:// (still with the secret): the bridge gives a client 10 s (websockets' open_timeout) from
    # accepting it to the WebSocket upgrade, and TLS + upgrade take four one-way delays after the
    # accept here (10.4 s): the bridge resets the connection.
    "2.6@64/16": Case("2.6 s, 64/16 kbit/s, ws://", 2.6, down_kbps=64, up_kbps=16, tls=False),
    "45": Case("45 s one way", 45.0),  # Mars at its closest is 3 minutes: a long link, in a bench's time
}
#: What a run of the bench flies by default: a ground run at 45 s would take over an hour.
DEFAULT_CASES = ("0", "1.3", "1.3+loss", "2.6@64/16")
#: The ways of flying a case: from the ground, onboard with a session of the runner's own, and
#: onboard handed to the supervisor whose session is open already.
MODES = ("ground", "onboard", "supervised")


def _ground_binding(
    folder: Path, robot: Robot, case: Case, credentials: dict[str, Path], status_throttle: float | None
) -> Path:
    data = yaml.safe_load(robot.binding.read_text())
    if status_throttle is not None:
        data["systems"][0]["options"]["status_throttle"] = status_throttle
    data["link"] = {"one_way_delay": case.delay, "outage_budget": 120}
    data["security"] = {"secret_file": str(credentials["rosbridge.secret"])}
    if case.tls:
        data["security"]["ca_file"] = str(credentials["ca.pem"])
    data["rosbridge"] = f"{'wss' if case.tls else 'ws'}://127.0.0.1:9090"
    for system in data["systems"]:
        system["sysrep"] = str((robot.binding.parent / system["sysrep"]).resolve())
    path = folder / "ground.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _deployment(
    folder: Path,
    robot: Robot,
    case: Case,
    credentials: dict[str, Path],
    binding: Path,
    seed: int,
    onboard: bool,
    displace: int | None,
) -> Path:
    source = robot.deployment
    data = yaml.safe_load(source.read_text())
    data.pop("demo", None)
    if displace is not None:
        data["displace"] = displace
    for key in ("scene", "robot", "templates", "robots"):
        data[key] = str((source.parent / data[key]).resolve())
    data["bridge"] = {"address": "127.0.0.1", "port": 0, "auth_secret_file": str(credentials["rosbridge.secret"])}
    if case.tls:
        data["bridge"].update(certfile=str(credentials["bridge.pem"]), keyfile=str(credentials["bridge.key"]))
    data["state_dir"] = str(folder / "state")
    data["bindings"] = [str(binding)]
    data["onboard"] = onboard
    link: dict[str, Any] = {"listen": "127.0.0.1:0", "delay": case.delay, "loss": case.loss, "seed": seed}
    if case.down_kbps:
        link.update(down_kbps=case.down_kbps, up_kbps=case.up_kbps)
    data["link"] = link
    path = folder / "habitat.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def fly(
    case: Case,
    *,
    time_scale: str,
    seed: int,
    env: dict[str, str],
    status_throttle: float | None = None,
    mode: str = "ground",
    robot: Robot = ROBOTS["iva"],
    displace: int | None = None,
) -> dict[str, Any]:
    """One run of ``robot``'s procedure across ``case``'s link, flown as ``mode`` says (:data:`MODES`),
    on its world as drawn or (``displace``) displaced by that seed; its figures."""
    from caretaker.certs import make_link_credentials
    from caretaker.demo import DEMO_APPROVER, demo_approver
    from caretaker.link import LinkControl
    from caretaker.processes import caretaker
    from pride.approvals import APPROVER_PASSWORD_ENV
    from pride.events import EventKind
    from records.audit_log import AuditLog

    with tempfile.TemporaryDirectory(prefix="caretaker-bench-link-") as tmp:
        folder = Path(tmp)
        credentials = make_link_credentials(folder / "link", ["127.0.0.1"], days=1)
        binding = _ground_binding(folder, robot, case, credentials, status_throttle)
        onboard = mode != "ground"
        deployment = _deployment(folder, robot, case, credentials, binding, seed, onboard, displace)
        up = caretaker("up", str(deployment), "--time-scale", time_scale, env=env, name="up")
        run = supervisor = None
        lines: list[tuple[float, str]] = []  # the runner's, each with the ground's clock when it came
        try:
            url = up.wait_for_line(r"^READY stack ", 300).split()[-1]
            db = f"sqlite:///{folder / 'audit.db'}"
            # a hazardous command (the IVA unlock) is approved by the demo's second operator, at once
            approver = {APPROVER_PASSWORD_ENV: demo_approver(db)}
            if mode == "supervised":  # its session open before the run: the opening is not the run's
                supervisor = caretaker(
                    "supervise", "--binding", str(binding), "--rosbridge", url, "--db", db, env=env, name="supervise"
                )
                supervisor.wait_for_line(r"^READY supervise ", case.delay * 10 + 120)
            started = time.monotonic()
            run = caretaker(
                "run",
                str(robot.procedure),
                "--binding",
                str(binding),
                "--rosbridge",
                url,
                "--auto",
                "--user",
                "bench",
                "--db",
                db,
                "--confirm-manual",
                *("--confirm-hazardous", "--approver", DEMO_APPROVER),
                *robot.run_options,
                *(["--onboard"] if onboard else []),
                *(["--via-supervisor"] if mode == "supervised" else []),
                env={**env, **approver},
                name="run",
                on_line=lambda _, line: lines.append((time.time(), line)),
            )
            words = run.wait_for_line(r"^RESULT ", 1800 + case.delay * 20).split()
            wall = time.monotonic() - started
            if words[1] != "completed":
                raise RuntimeError(f"{case.name}: the run ended {words[1]}:\n{run.tail(40)}")
            audit = AuditLog(db)
            try:
                events = audit.events(words[3])
            finally:
                audit.close()
            stats = LinkControl(folder / "state" / "link.sock").stats()
            with contextlib.closing(sqlite3.connect(folder / "state" / "ledger" / "command_ledger.sqlite")) as ledger:
                records = ledger.execute("SELECT service, finished - started FROM commands").fetchall()
            arrived = _unit_arrival(folder / "state" / "onboard") if onboard else None
        finally:
            for process in (run, supervisor):
                if process is not None:
                    process.stop()
            up.stop()
    first = next(e.time for e in events if e.kind is EventKind.RUN_STARTED)
    last = next(e.time for e in events if e.kind is EventKind.RUN_COMPLETED)
    answers = 3 if onboard else sum(e.kind is EventKind.COMMAND_SENT for e in events)
    habitat = sum(seconds for _, seconds in records)
    motion = sum(seconds for service, seconds in records if service.endswith("/execute_command"))
    run_s = (last - first).total_seconds()
    bound = habitat + answers * 2 * case.delay
    seen = on_habitat = limit = None
    if arrived is not None:
        sent = next(t for t, line in lines if " goes up to " in line or line.startswith("handed run "))
        seen = next(t for t, line in lines if line.startswith("RESULT ")) - sent
        on_habitat = last.timestamp() - arrived
        limit = on_habitat + 1.5 * 2 * case.delay
    return {
        "case": case.name,
        "mode": mode,
        "seen": seen,
        "on_habitat": on_habitat,
        "limit": limit,
        "wall": wall,
        "run": run_s,
        "habitat": habitat,
        "motion": motion,
        "N": answers,
        "verifies": sum(e.kind is EventKind.TELEMETRY_SEEN for e in events),
        "bound": bound,
        "ratio": run_s / bound,
        "up": stats.up_bytes,
        "down": stats.down_bytes,
        "stalls": stats.up_stalls + stats.down_stalls,
    }


def _unit_arrival(onboard_state: Path) -> float:
    """When the unit reached the habitat (epoch s): its files were written there as it arrived,
    before the habitat started its run."""
    return min(path.stat().st_mtime for path in onboard_state.glob("units/*/*") if path.name != "unit.json")


def _seconds(value: float | None) -> str:
    return "–" if value is None else f"{value:.1f} s"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases",
        default=",".join(DEFAULT_CASES),
        help=f"comma-separated, of {', '.join(CASES)} (default {','.join(DEFAULT_CASES)})",
    )
    parser.add_argument("--modes", default="ground,onboard", help=f"comma-separated, of {', '.join(MODES)}")
    parser.add_argument("--time-scale", default="1", help="simulation speed (1: real motion time; default 1)")
    parser.add_argument("--seed", type=int, default=7, help="the link's loss seed (default 7)")
    parser.add_argument("--robot", choices=sorted(ROBOTS), default="iva", help="whose procedure to fly (default iva)")
    parser.add_argument(
        "--displace", type=int, metavar="SEED", help="the world displaced by this seed (sim --displace)"
    )
    parser.add_argument(
        "--status-throttle", type=float, help="at_telemetry's status_throttle (s; default the plugin's)"
    )
    args = parser.parse_args(argv)
    unknown = [name for name in args.cases.split(",") if name not in CASES]
    if unknown:
        parser.error(f"unknown cases {unknown}; cases are {', '.join(CASES)}")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(101, 200)))
    env = dict(os.environ)
    modes = args.modes.split(",")
    if not set(modes) <= set(MODES):
        parser.error(f"--modes takes {', '.join(MODES)}, not {args.modes}")
    print(
        "| link | mode | run | wall | habitat (motion) | N | bound | ratio | seen | on habitat | limit "
        "| bytes up | bytes down | stalls |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.cases.split(","):
        for mode in modes:
            r = fly(
                CASES[name],
                time_scale=args.time_scale,
                seed=args.seed,
                env=env,
                status_throttle=args.status_throttle,
                mode=mode,
                robot=ROBOTS[args.robot],
                displace=args.displace,
            )
            print(
                f"| {r['case']} | {r['mode']} | {r['run']:.1f} s | {r['wall']:.1f} s "
                f"| {r['habitat']:.1f} s ({r['motion']:.1f} s) | {r['N']} | {r['bound']:.1f} s | {r['ratio']:.2f}× "
                f"| {_seconds(r['seen'])} | {_seconds(r['on_habitat'])} | {_seconds(r['limit'])} "
                f"| {r['up'] / 1024:.1f} KiB | {r['down'] / 1024:.1f} KiB | {r['stalls']} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
