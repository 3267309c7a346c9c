"""What a robot side costs while nothing happens: CPU of each part of an idle stack.

    .venv/bin/python bench/idle_stack.py [deployments/iva.yaml] [--seconds 20] [--time-scale 1]

Starts ``caretaker up DEPLOYMENT`` (its own ROS domain, loopback), waits for ``READY stack`` and a
few seconds more, then measures each process's CPU (user + system, from ``/proc``) over
``--seconds`` and prints it as a share of one core, part by part. A habitat computer runs its robot
side all day, mostly waiting, and the test suite runs several at once: idle must cost next to nothing.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import psutil

REPO = Path(__file__).resolve().parents[1]
SETTLE_S = 5.0


def cpu_seconds(process: psutil.Process) -> float:
    try:
        times = process.cpu_times()
    except psutil.Error:
        return 0.0
    return float(times.user + times.system)


def part_name(process: psutil.Process) -> str:
    try:
        words = process.cmdline()
    except psutil.Error:
        return "(ended)"
    return " ".join(Path(w).name for w in words[1:3]) if len(words) > 2 else " ".join(words)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("deployment", nargs="?", default=str(REPO / "deployments" / "iva.yaml"))
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--time-scale", default="1")
    parser.add_argument("--domain", default="87", help="ROS_DOMAIN_ID of the stack (default: 87)")
    args = parser.parse_args()
    env = dict(os.environ, ROS_DOMAIN_ID=args.domain, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    command = [sys.executable, "-m", "caretaker.cli", "up", args.deployment, "--bridge-port", "0"]
    command += ["--time-scale", args.time_scale]
    up = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert up.stdout is not None
        for line in up.stdout:
            if line.startswith("READY stack"):
                break
        else:
            print(f"caretaker up ended before READY (exit {up.wait()})", file=sys.stderr)
            return 1
        time.sleep(SETTLE_S)  # measuring idle: the parts' start-up is over
        parts = [psutil.Process(up.pid), *psutil.Process(up.pid).children(recursive=True)]
        before = {p.pid: cpu_seconds(p) for p in parts}
        began = time.monotonic()
        time.sleep(args.seconds)  # the measurement window itself
        elapsed = time.monotonic() - began
        total = 0.0
        print(f"idle {Path(args.deployment).name}, {elapsed:.0f} s, time scale {args.time_scale}:")
        for process in parts:
            share = 100 * (cpu_seconds(process) - before[process.pid]) / elapsed
            total += share
            print(f"{share:6.1f} % of a core  {part_name(process)}")
        print(f"{total:6.1f} % of a core  in all")
    finally:
        up.terminate()
        up.wait(60)
    return 0


if __name__ == "__main__":
    sys.exit(main())
