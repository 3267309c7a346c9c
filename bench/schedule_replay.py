"""What the test scheduler's core budget costs in wall time, with no congestion: a replay of its rules.

    .venv/bin/python bench/schedule_replay.py [--stretch 1.6] [--budgets 1.0,1.25,1.5,2.0] [--workers 4,6,8]

reads ``tests/file_costs.json`` and replays, for each budget and number of workers, the rules of
``tests/support/file_schedule.py``: a free worker takes the longest file whose cores fit what the
running files leave of the budget; with nothing running it takes the file of fewest cores. Each
file lasts its measured seconds times ``--stretch`` (how much slower this machine is than the one
that measured them) and nothing slows it down: the result is a floor, for comparing budgets, not a
forecast. A budget above what the cores carry looks faster here and is slower on the machine, whose
files then wait for the CPU and spend more of it (docs/benchmarks.md, "The suite's schedule").
"""

from __future__ import annotations

import argparse
import heapq
import json
from pathlib import Path

COSTS = Path(__file__).resolve().parents[1] / "tests" / "file_costs.json"


def makespan(files: dict[str, tuple[float, float]], budget: float, workers: int) -> float:
    """Seconds until the last file ends: ``files`` maps a file to (seconds, cores)."""
    queue = sorted(files.items(), key=lambda item: -item[1][0])
    running: list[tuple[float, float]] = []  # (ends at, cores)
    now = 0.0
    while queue or running:
        while queue and len(running) < workers:
            room = budget - sum(cores for _, cores in running)
            chosen = next((item for item in queue if item[1][1] <= room + 1e-9), None)
            if chosen is None and not running:
                chosen = min(queue, key=lambda item: item[1][1])
            if chosen is None:
                break
            queue.remove(chosen)
            seconds, cores = chosen[1]
            heapq.heappush(running, (now + seconds, cores))
        now, _ = heapq.heappop(running)
    return now


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--stretch", type=float, default=1.6, help="this machine's time for the measured files' 1 s")
    parser.add_argument("--budgets", default="1.0,1.25,1.5,2.0", help="core budgets, comma-separated")
    parser.add_argument("--workers", default="4,6,8", help="numbers of workers, comma-separated")
    args = parser.parse_args()
    costs = json.loads(COSTS.read_text(encoding="utf-8"))
    files = {name: (float(c["seconds"]) * args.stretch, float(c["cores"])) for name, c in costs.items()}
    workers = [int(w) for w in args.workers.split(",")]
    print("budget  " + "  ".join(f"{w} workers" for w in workers) + "   (minutes)")
    for budget in (float(b) for b in args.budgets.split(",")):
        print(f"{budget:6.2f}  " + "  ".join(f"{makespan(files, budget, w) / 60:9.1f}" for w in workers))


if __name__ == "__main__":
    main()
