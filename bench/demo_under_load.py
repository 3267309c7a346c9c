"""`caretaker demo` with and without CPU hogs beside it, interleaved in one run.

Usage: .venv/bin/python bench/demo_under_load.py [--runs 5] [--hogs 2] [--time-scale 1] [iva eva]

For each deployment, ``--runs`` demos run beside ``--hogs`` busy processes (bench/cpu_load.py)
and as many without, alternating, so both see the same machine. A demo passes when it exits 0:
the procedure completed and its world check held (``caretaker demo`` checks the simulator's
world, not the run's own account). Prints each run's outcome and wall time, then per deployment
how many passed and the median time with hogs over the median without. Exit status 1 if any
demo failed; the failed run's last output lines are printed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from bench.cpu_load import cpu_hogs

REPO = Path(__file__).resolve().parents[1]
CARETAKER = REPO / ".venv" / "bin" / "caretaker"


@dataclass(frozen=True)
class Run:
    deployment: str
    hogs: int
    passed: bool
    seconds: float
    tail: str


def demo(deployment: str, hogs: int, time_scale: str, workdir: Path) -> Run:
    """One ``caretaker demo`` (its audit log and report in ``workdir``) beside ``hogs`` hogs."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.setdefault("ROS_DOMAIN_ID", str(50 + os.getpid() % 40))
    command = [
        str(CARETAKER),
        "demo",
        deployment,
        "--time-scale",
        time_scale,
        "--bridge-port",
        "0",
        "--db",
        f"sqlite:///{workdir / 'audit.db'}",
        "--reports",
        str(workdir / "reports"),
    ]
    with cpu_hogs(hogs):
        started = time.monotonic()
        done = subprocess.run(command, env=env, cwd=workdir, capture_output=True, text=True, timeout=1800)
        seconds = time.monotonic() - started
    output = (done.stdout + done.stderr).strip().splitlines()
    return Run(deployment, hogs, done.returncode == 0, seconds, "\n".join(output[-15:]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench/demo_under_load.py", description=__doc__.splitlines()[0])
    parser.add_argument("deployments", nargs="*", default=["iva", "eva"])
    parser.add_argument("--runs", type=int, default=5, help="demos per deployment with hogs (and as many without)")
    parser.add_argument("--hogs", type=int, default=2, help="busy processes beside a loaded demo")
    parser.add_argument("--time-scale", default="1", help="the demos' --time-scale (default 1: real time)")
    args = parser.parse_args(argv)
    runs: list[Run] = []
    with tempfile.TemporaryDirectory(prefix="demo-under-load-") as tmp:
        for deployment in args.deployments:
            for i in range(args.runs):
                for hogs in (0, args.hogs):
                    workdir = Path(tmp) / f"{deployment}-{i}-{hogs}"
                    workdir.mkdir()
                    run = demo(deployment, hogs, args.time_scale, workdir)
                    runs.append(run)
                    print(
                        f"{deployment} run {i + 1} with {hogs} hogs: {'passed' if run.passed else 'FAILED'} "
                        f"in {run.seconds:.1f} s",
                        flush=True,
                    )
                    if not run.passed:
                        print(run.tail, flush=True)
    print("\n| deployment | hogs | passed | median s | min–max s | median ÷ without hogs |\n|---|---|---|---|---|---|")
    for deployment in args.deployments:
        quiet = statistics.median(r.seconds for r in runs if r.deployment == deployment and r.hogs == 0)
        for hogs in (0, args.hogs):
            mine = [r for r in runs if r.deployment == deployment and r.hogs == hogs]
            times = [r.seconds for r in mine]
            print(
                f"| {deployment} | {hogs} | {sum(r.passed for r in mine)}/{len(mine)} | {statistics.median(times):.1f} "
                f"| {min(times):.1f}–{max(times):.1f} | {statistics.median(times) / quiet:.2f} |"
            )
    return 0 if all(r.passed for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
