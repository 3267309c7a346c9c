"""Where the test suite's time goes, file by file: wall time and CPU of each test file.

    .venv/bin/python bench/suite_profile.py [--out FILE.jsonl] [--save-costs] -- PYTEST_ARGS...

runs ``pytest PYTEST_ARGS`` with this module loaded as a plugin (``-p suite_profile``), then prints
every test file's wall time (first setup to last teardown, module fixtures included) and CPU
seconds, sorted by wall time, and the sums. ``make test``'s length is set by how these files
pack onto the workers beside the longest one, and on two cores by the CPU they need together.

CPU is the worker's own plus that of every child it reaped during the file (a child's figure
includes the grandchildren it reaped: a robot stack's parts) plus what its live descendants used
meanwhile (the worker's shared Chromium, with the renderers it reaped). A process that is not the
worker's descendant (the session's PostgreSQL server, started detached) is not counted; a file's
figure is therefore a floor.

``--save-costs`` writes each file's wall time and share of a core (CPU over wall) into
``tests/file_costs.json``, which the suite's scheduler reads (tests/support/file_schedule.py): run
it with ``make test``'s own pytest arguments, so the figures are those of files sharing the machine
as they do there.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Generator
from pathlib import Path

import psutil
import pytest

#: The plugin's output file, set by ``main`` for the pytest it starts (and inherited by workers).
OUT_ENV = "CARETAKER_SUITE_PROFILE"
COSTS = Path(__file__).resolve().parents[1] / "tests" / "file_costs.json"

_started: dict[str, tuple[float, float, float, dict[tuple[int, float], float]]] = {}


def _cpu_seconds() -> float:
    """This process's CPU and that of the children it reaped (a child's figure includes the
    grandchildren it reaped: a robot stack's parts)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _live_descendants() -> dict[tuple[int, float], float]:
    """CPU seconds of each live descendant (with what it reaped), by pid and start time."""
    found = {}
    for process in psutil.Process().children(recursive=True):
        try:
            times = process.cpu_times()
            found[(process.pid, process.create_time())] = (
                times.user + times.system + times.children_user + times.children_system
            )
        except psutil.Error:
            continue  # ended meanwhile
    return found


def _grown(before: dict[tuple[int, float], float]) -> float:
    """What the live descendants used since ``before``: a worker's shared Chromium lives from file
    to file, so only its growth during a file is that file's. One that ended meanwhile is left out
    (reaped by the worker, it is in :func:`_cpu_seconds`)."""
    return sum(cpu - before.get(key, 0.0) for key, cpu in _live_descendants().items())


def _file_of(item: pytest.Item | None) -> str | None:
    return None if item is None else item.nodeid.split("::", 1)[0]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None]:
    """Stamp a file's first setup and, after its last teardown (module fixtures too), write its figures."""
    name = _file_of(item)
    assert name is not None
    if name not in _started:
        _started[name] = (time.time(), time.monotonic(), _cpu_seconds(), _live_descendants())
    yield
    out = os.environ.get(OUT_ENV)
    if out and _file_of(nextitem) != name:
        began, wall0, cpu0, live0 = _started[name]
        record = {
            "file": name,
            "began": round(began, 1),  # the clock's time, so the workers' files line up on one timeline
            "wall_s": round(time.monotonic() - wall0, 1),
            "cpu_s": round(_cpu_seconds() - cpu0 + _grown(live0), 1),
            "worker": os.environ.get("PYTEST_XDIST_WORKER", "main"),
        }
        with open(out, "a", encoding="utf-8") as stream:  # one short line per write: appends do not interleave
            stream.write(json.dumps(record) + "\n")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, help="keep the per-file records here (JSON lines)")
    parser.add_argument("--save-costs", action="store_true", help=f"write the figures into {COSTS}")
    parser.add_argument("pytest_args", nargs=argparse.REMAINDER, help="-- then pytest's arguments")
    args = parser.parse_args()
    pytest_args = [a for a in args.pytest_args if a != "--"] or ["tests"]
    out = args.out or Path(tempfile.mkdtemp(prefix="suite-profile-")) / "files.jsonl"
    out.unlink(missing_ok=True)
    env = dict(os.environ, **{OUT_ENV: str(out)})
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(Path(__file__).parent), env.get("PYTHONPATH")]))
    began = time.monotonic()
    status = subprocess.call([sys.executable, "-m", "pytest", "-p", "suite_profile", *pytest_args], env=env)
    wall = time.monotonic() - began
    records = [json.loads(line) for line in out.read_text(encoding="utf-8").splitlines()] if out.exists() else []
    records.sort(key=lambda r: -r["wall_s"])
    print(f"\n{'wall s':>8} {'CPU s':>8}  worker  file")
    for r in records:
        print(f"{r['wall_s']:8.1f} {r['cpu_s']:8.1f}  {r['worker']:6}  {r['file']}")
    total_wall = sum(r["wall_s"] for r in records)
    total_cpu = sum(r["cpu_s"] for r in records)
    print(f"{total_wall:8.1f} {total_cpu:8.1f}  (sums over {len(records)} files; pytest ran {wall:.0f} s)")
    print(f"records: {out}")
    if args.save_costs:
        cores = float(os.cpu_count() or 1)  # a file of a few ms has a ratio of CPU to wall time that means nothing
        costs = {
            r["file"]: {
                "seconds": round(r["wall_s"]),
                "cores": round(min(cores, r["cpu_s"] / max(r["wall_s"], 0.1)), 2),
            }
            for r in sorted(records, key=lambda r: r["file"])
        }
        lines = ",\n".join(f" {json.dumps(name)}: {json.dumps(cost)}" for name, cost in costs.items())
        COSTS.write_text("{\n" + lines + "\n}\n", encoding="utf-8")  # a file a line: diffs stay readable
        print(f"costs of {len(costs)} files: {COSTS}")
    return status


if __name__ == "__main__":
    sys.exit(main())
