"""Where the CPU goes while a command runs: CPU seconds per Caretaker part, browser, database...

    .venv/bin/python bench/cpu_by_part.py -- .venv/bin/pytest -n 3 --dist loadfile tests

Every process on the machine is looked at once a second (``/proc``); each one's CPU time
(user + system) is counted from when it was first seen (processes already running when the
command starts count only what they use after it), and summed by part: ``caretaker sim``,
``caretaker at-server``, Chromium, PostgreSQL and so on. A process that lives less than a second
between two looks is missed, so the table is a lower bound; the total line says how much of the
machine the command's time was.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import threading
import time
from collections import Counter
from dataclasses import dataclass

TICK = os.sysconf("SC_CLK_TCK")
PARTS = ("chrom", "java", "postgres", "node", "mvn")


@dataclass
class Seen:
    part: str
    base: float  # CPU s when first seen (0 for a process that started during the command)
    cpu: float


def part_of(cmdline: str) -> str:
    """The part a process belongs to, from its command line."""
    named = re.search(r"caretaker (\S+)", cmdline)
    if named:
        return f"caretaker {named.group(1)}"
    for part in PARTS:
        if part in cmdline:
            return part
    if "pytest" in cmdline or "execnet" in cmdline or "xdist" in cmdline:
        return "pytest (and its in-process clients)"
    return os.path.basename(cmdline.split(" ")[0]) or "?"


def look(seen: dict[tuple[str, str], Seen], first: bool) -> None:
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/stat") as f:
                stat = f.read()
            with open(f"/proc/{pid}/cmdline") as f:
                cmdline = f.read().replace("\0", " ").strip()
        except OSError:
            continue  # ended between listing and reading
        fields = stat.rsplit(")", 1)[1].split()
        cpu = (int(fields[11]) + int(fields[12])) / TICK
        key = (pid, fields[19])  # a pid with its start time: pids are reused
        if key in seen:
            seen[key].cpu = cpu
        else:
            seen[key] = Seen(part_of(cmdline), cpu if first else 0.0, cpu)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command to measure (after --)")
    args = parser.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("give the command to measure after --")
    seen: dict[tuple[str, str], Seen] = {}
    look(seen, first=True)
    done = threading.Event()

    def sample() -> None:
        while not done.wait(1.0):
            look(seen, first=False)

    sampler = threading.Thread(target=sample, daemon=True)
    started = time.monotonic()
    sampler.start()
    code = subprocess.call(command)
    done.set()
    sampler.join()
    wall = time.monotonic() - started
    by_part: dict[str, float] = {}
    count: Counter[str] = Counter()
    for s in seen.values():
        if s.cpu > s.base:
            by_part[s.part] = by_part.get(s.part, 0.0) + s.cpu - s.base
            count[s.part] += 1
    total = sum(by_part.values())
    print(f"\n{'CPU s':>9} {'share':>6} {'procs':>6}  part", file=sys.stderr)
    for part, cpu in sorted(by_part.items(), key=lambda item: -item[1])[:25]:
        print(f"{cpu:9.1f} {cpu / total:6.1%} {count[part]:6d}  {part}", file=sys.stderr)
    cores = os.cpu_count() or 1
    print(
        f"{total:9.1f} CPU s in {wall:.0f} s of wall time: {total / wall / cores:.0%} of {cores} cores (exit {code})",
        file=sys.stderr,
    )
    return code


if __name__ == "__main__":
    sys.exit(main())
