"""Where the CPU goes while a command runs: CPU seconds per Caretaker part, browser, database...

    .venv/bin/python bench/cpu_by_part.py -- .venv/bin/pytest -n 3 --dist loadfile tests

Every process on the machine is looked at once a second (``/proc``); each one's CPU time
(user + system) is counted from when it was first seen (processes already running when the
command starts count only what they use after it), and summed by part: ``caretaker sim``,
``caretaker at-server``, Chromium, PostgreSQL and so on. A process that lives less than a second
between two looks is missed, so the table is a lower bound; the total line says how much of the
machine the command's time was.

``--accounting FILE`` (root) also turns on the kernel's process accounting into FILE while the
command runs (``accton``, Debian's ``acct``): every process that ended is recorded with its CPU,
so the ones the looks missed are added, by their command name (``short: NAME``), and the table
is the whole of what ran.
"""

from __future__ import annotations

import argparse
import os
import re
import struct
import subprocess
import sys
import threading
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

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


#: struct acct_v3 (linux/acct.h): flag, version, tty, exitcode, uid, gid, pid, ppid, btime,
#: etime, then comp_t utime, stime, mem, io, rw, minflt, majflt, swaps, and the command's name.
ACCT_V3 = struct.Struct("<BBHIIIIIIf8H16s")


def _comp(value: int) -> float:
    """A comp_t (13-bit mantissa, base-8 exponent) of clock ticks, in seconds."""
    return ((value & 0x1FFF) << (3 * (value >> 13))) / TICK


def ended_processes(path: Path) -> list[tuple[int, float, str, float]]:
    """(pid, start in Unix seconds, command name, CPU s) of each process the accounting file records."""
    data = path.read_bytes()
    records = []
    for offset in range(0, len(data) - ACCT_V3.size + 1, ACCT_V3.size):
        fields = ACCT_V3.unpack_from(data, offset)
        if fields[1] != 3:
            raise ValueError(f"{path}: record {offset // ACCT_V3.size} is not acct v3 (version {fields[1]})")
        name = fields[18].split(b"\0", 1)[0].decode(errors="replace")
        records.append((fields[6], float(fields[8]), name, _comp(fields[10]) + _comp(fields[11])))
    return records


def _boot_time() -> float:
    with open("/proc/stat") as f:
        return float(next(line.split()[1] for line in f if line.startswith("btime ")))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--accounting", type=Path, help="also count every process that ended (kernel accounting, root)")
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
    if args.accounting:
        args.accounting.unlink(missing_ok=True)
        args.accounting.touch()
        subprocess.run(["accton", str(args.accounting)], check=True)
    started = time.monotonic()
    sampler.start()
    try:
        code = subprocess.call(command)
    finally:
        if args.accounting:
            subprocess.run(["accton", "off"], check=True)
    done.set()
    sampler.join()
    wall = time.monotonic() - started
    by_part: dict[str, float] = {}
    count: Counter[str] = Counter()
    for s in seen.values():
        if s.cpu > s.base:
            by_part[s.part] = by_part.get(s.part, 0.0) + s.cpu - s.base
            count[s.part] += 1
    if args.accounting:  # the processes no look saw: a pid seen started within a second of the record's start
        boot = _boot_time()
        looked: dict[int, list[float]] = {}
        for seen_pid, seen_start in seen:
            looked.setdefault(int(seen_pid), []).append(boot + int(seen_start) / TICK)
        for pid, began, name, cpu in ended_processes(args.accounting):
            if not any(abs(t - began) <= 1.5 for t in looked.get(pid, [])):
                by_part[f"short: {name}"] = by_part.get(f"short: {name}", 0.0) + cpu
                count[f"short: {name}"] += 1
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
