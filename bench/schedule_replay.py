"""What the test scheduler's core budget costs in wall time, with no congestion: the scheduler itself, replayed.

    .venv/bin/python bench/schedule_replay.py [--stretch 1.0] [--budgets 1.25,1.5,2.0] [--workers 4,8] [--tests 3]

drives ``tests/support/file_schedule.py``'s :class:`CostAwareFileScheduling` (the class ``make test``
uses, its own choices and holds) over ``tests/file_costs.json`` on a clock of its own, with stand-in
workers that behave as pytest-xdist's do: each file is ``--tests`` tests of equal length, its
measured seconds times ``--stretch`` in all, and a worker runs a test only once it knows the next
(or was told to shut down), so a file is asked for while its worker still runs the one before;
held workers are looked at again when a test ends and every ``RETRY_HELD_S``, as in ``make test``.
Nothing slows a file down here: the minutes are a floor, for comparing budgets, not a forecast.
Beside them, the most cores the running files summed to, and the share of the run they were above
the budget (files given to a worker still busy start unchecked; a worker alone takes a file
heavier than the budget).
"""

from __future__ import annotations

import argparse
import sys
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from xdist.remote import Producer  # type: ignore[import-untyped]  # noqa: E402

from support.file_schedule import COSTS, RETRY_HELD_S, CostAwareFileScheduling, file_cost  # noqa: E402


@dataclass
class _Config:
    """What the scheduler reads of pytest's configuration."""

    rootpath: Path
    workers: int

    def getvalue(self, name: str) -> list[str]:
        assert name == "tx", name
        return [f"{self.workers}*popen"]


@dataclass(eq=False)
class _Worker:
    """A stand-in for pytest-xdist's worker: the tests it was sent, in order, and the one it runs."""

    collection: list[str]
    queue: deque[str] = field(default_factory=deque)
    running: tuple[str, float] | None = None  # the test and when it ends
    shutting_down: bool = False

    def send_runtest_some(self, indices: list[int]) -> None:
        self.queue.extend(self.collection[i] for i in indices)

    def shutdown(self) -> None:
        self.shutting_down = True


@dataclass(frozen=True)
class Replay:
    """How one replay went."""

    minutes: float
    peak_cores: float
    over_budget: float  # the share of the run the running files' cores were above the budget


def replay(budget: float, workers: int, stretch: float, tests: int) -> Replay:
    """Run the suite's files on ``workers`` stand-in workers under the real scheduler at ``budget``."""
    files = sorted(_files(), key=lambda name: -file_cost(REPO / name, REPO).seconds)
    collection = [f"{name}::test_{i}" for name in files for i in range(tests)]
    quiet = Producer("replay", enabled=False)
    scheduler = CostAwareFileScheduling(_Config(REPO, workers), quiet)  # a stand-in config
    scheduler.budget = budget
    now = 0.0
    scheduler.clock = lambda: now
    nodes = [_Worker(collection) for _ in range(workers)]
    for node in nodes:
        scheduler.add_node(node)
        scheduler.add_node_collection(node, collection)
    scheduler.workqueue = OrderedDict((name, {f"{name}::test_{i}": False for i in range(tests)}) for name in files)
    scheduler.collection = collection
    for node in nodes:
        scheduler._assign_work_unit(node)
    for node in nodes:
        scheduler._reschedule(node)
    peak = over = 0.0
    while True:
        for node in nodes:  # a worker runs a test once it knows the next, or was told to stop
            if node.running is None and (len(node.queue) >= 2 or (node.queue and node.shutting_down)):
                nodeid = node.queue[0]
                file = nodeid.split("::", 1)[0]
                node.running = (nodeid, now + file_cost(REPO / file, REPO).seconds * stretch / tests)
        busy = [node for node in nodes if node.running is not None]
        if not busy:
            break
        cores = sum(file_cost(REPO / n.running[0].split("::", 1)[0], REPO).cores for n in busy if n.running)
        node = min(busy, key=lambda n: n.running[1] if n.running else 0.0)
        assert node.running is not None
        nodeid, ends = node.running
        peak = max(peak, cores)
        tick = (now // RETRY_HELD_S + 1) * RETRY_HELD_S  # the controller's retry of held workers
        over += (min(ends, tick) - now) if cores > budget + 1e-9 else 0.0
        if tick < ends:
            now = tick
            scheduler._retry_held()
            continue
        now, node.running = ends, None
        node.queue.popleft()
        scheduler.mark_test_complete(node, collection.index(nodeid))
    left = sum(len(node.queue) for node in nodes) + len(scheduler.workqueue)
    if left:
        raise RuntimeError(f"the replay stalled at {now / 60:.1f} min with {left} tests or files left")
    return Replay(now / 60, peak, over / now if now else 0.0)


def _files() -> list[str]:
    """Every test module of the suite, measured or not (an unmeasured one costs what its mark says)."""
    return sorted({p.relative_to(REPO).as_posix() for p in (REPO / "tests").rglob("test_*.py")})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--stretch", type=float, default=1.0, help=f"this machine's time for {COSTS}'s 1 s")
    parser.add_argument("--budgets", default="1.25,1.5,2.0", help="core budgets, comma-separated")
    parser.add_argument("--workers", default="4,8", help="numbers of workers, comma-separated")
    parser.add_argument("--tests", type=int, default=3, help="tests per file")
    args = parser.parse_args()
    workers = [int(w) for w in args.workers.split(",")]
    print("budget  " + "  ".join(f"{w:2d} workers: min, peak cores, time over" for w in workers))
    for budget in (float(b) for b in args.budgets.split(",")):
        cells = []
        for count in workers:
            r = replay(budget, count, args.stretch, args.tests)
            cells.append(f"{r.minutes:6.1f} {r.peak_cores:5.2f} {r.over_budget:6.1%}             ")
        print(f"{budget:6.2f}  " + "  ".join(cells))


if __name__ == "__main__":
    main()
