"""What a command costs to start: user + system CPU-s of it and the processes it waited for.

    .venv/bin/python bench/start_cpu.py --repeat 7 -- .venv/bin/caretaker accounts --db sqlite:///x.db list
    .venv/bin/python bench/start_cpu.py --ready '^READY stack ' -- \\
        .venv/bin/caretaker up deployments/iva.yaml --time-scale 0 --bridge-port 0

``--ready REGEX`` stops the command (Ctrl-C to its process group, as tests/support/stack.py does)
once it printed a matching line, so a server's start and stop are measured. ``--variant
NAME=VALUE[,NAME=VALUE]`` adds a run of the same command with those variables set (an empty
``--variant ''`` is the command as it is): the variants run one after the other, ``--repeat`` times
over, so a machine that slows down slows every variant alike; the medians and their ratios to the
first variant are printed. The CPU is the kernel's count for the command and every descendant it
waited for (``wait4``), as ``/usr/bin/time`` gives it: a command that leaves children to others is
undercounted (``caretaker up`` and ``caretaker demo`` wait for their parts).
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import statistics
import subprocess
import sys
import time


def measure(command: list[str], env: dict[str, str], ready: str | None) -> tuple[float, float]:
    """(CPU-s, wall s) of one run of ``command``, stopped after its first line matching ``ready``."""
    started = time.monotonic()
    proc = subprocess.Popen(
        command,
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    assert proc.stdout is not None
    pattern = re.compile(ready) if ready else None
    last = ""
    for line in proc.stdout:
        last = line
        if pattern is not None and pattern.search(line):
            os.killpg(proc.pid, signal.SIGINT)
            pattern = None
    _, status, usage = os.wait4(proc.pid, 0)
    if pattern is not None or os.waitstatus_to_exitcode(status) != 0:
        print(f"exit status {os.waitstatus_to_exitcode(status)}, ready: {pattern is None}; last line: {last.rstrip()}")
    return usage.ru_utime + usage.ru_stime, time.monotonic() - started


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--ready", metavar="REGEX", help="stop the command once it printed a matching line")
    parser.add_argument("--variant", action="append", metavar="NAME=VALUE,...", help="environment of one variant")
    parser.add_argument("command", nargs="+")
    args = parser.parse_args()
    variants = args.variant or [""]
    cpu: dict[str, list[float]] = {variant: [] for variant in variants}
    for _ in range(args.repeat):
        for variant in variants:
            env = dict(os.environ)
            env.update(item.split("=", 1) for item in variant.split(",") if item)
            seconds, wall = measure(args.command, env, args.ready)
            cpu[variant].append(seconds)
            print(f"{variant or '(as it is)'}: {seconds:.2f} CPU-s in {wall:.1f} s", flush=True)
    first = statistics.median(cpu[variants[0]])
    for variant, values in cpu.items():
        median = statistics.median(values)
        runs = " ".join(f"{value:.2f}" for value in values)
        print(f"median {median:.2f} CPU-s ({median / first:.2f} of the first) [{runs}] {variant or '(as it is)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
