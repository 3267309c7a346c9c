"""Which test file runs where: whole files to pytest-xdist workers, longest first, within the machine's cores.

What a file costs is measured: ``bench/suite_profile.py --save-costs`` writes each file's wall
time and the share of a core its processes kept busy into ``tests/file_costs.json``. A file not
measured yet states its length with ``pytest.mark.slow(seconds=N)`` in its ``pytestmark`` and is
taken to keep a whole core busy. :func:`file_cost` reads both from the files themselves, because
the scheduler runs in pytest-xdist's controller, which never imports the test modules.

pytest-xdist's own file scheduling hands a worker its next file while the worker's current file
still has two tests to run (a worker cannot finish a test before it knows the next one: the
fixtures to tear down depend on it). For a file of one long test that happens the moment it starts:
the ten-minute outage test got a two-minute file queued behind it, which then waited ten minutes
while the other workers ran out of work. And it hands out files in order, whatever they cost:
more workers than cores ran several robot stacks and browsers at once, each slower for it.

:class:`CostAwareFileScheduling` gives the next longest file only to the worker that will be free
first (a worker still busy for longer than another gets the shortest file that fits instead), and
only if the cores of the files running then stay within :data:`CORE_BUDGET`. When the longest file
does not fit, it is reserved the time the running files will have freed its cores, as a batch
system's backfilling does: until then a worker only takes a file that fits and ends before it, so
lighter files never keep the heavy ones to the run's end, where they would all run together (a file
heavier than :data:`HEAVIEST_NEED` of the budget starts once that much is free). A worker given
nothing is held, and looked at again when a test ends elsewhere and every :data:`RETRY_HELD_S`: one
between files, or with two tests or more still to run, for as long as nothing fits; one whose file
has a single test left (pytest-xdist runs a worker's last test only once it knows the next) for at
most :data:`LAST_TEST_HELD_S`, then it gets the file of least CPU. A worker is never held when no
other worker is running a test, so the suite cannot stall. Files that mostly wait (a link's light
time, a ten-minute outage) thus run beside the ones that compute, on workers beyond the cores, while
the ones that compute never run more at once than the cores can carry: a file stretched by a crowded
machine costs more CPU, not less (its simulator, its browser and its robot's nodes keep a share of a
core for as long as they live). ``bench/schedule_replay.py`` replays this class over the measured
costs.
"""

from __future__ import annotations

import json
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import pytest

# pytest-xdist ships no type information.
from xdist.remote import Producer  # type: ignore[import-untyped]
from xdist.scheduler import LoadFileScheduling  # type: ignore[import-untyped]
from xdist.workermanage import WorkerController  # type: ignore[import-untyped]

__all__ = ["COSTS", "CostAwareFileScheduling", "FileCost", "file_cost", "longest_files_first"]

#: Measured costs (bench/suite_profile.py --save-costs), relative to the repository, as are the
#: test files named in it.
COSTS = Path("tests/file_costs.json")
#: What a file marked ``slow`` without ``seconds=`` is taken to last.
SLOW_DEFAULT_S = 30.0
#: What an unmarked file (unit tests) is taken to last.
QUICK_S = 1.0
#: The sum of the running files' cores the scheduler stays within while it can: CI's two cores. The
#: figures in tests/file_costs.json are what each file needs on CI's machine, the heaviest measured
#: two at a time there (``bench/suite_profile.py -- -n 2``), so a figure is close to the file's own
#: demand, not its share of a crowded machine (an earlier table of shares, read against a budget of
#: 1.25, let files needing four or five cores run at once on two).
CORE_BUDGET = 2.0

#: How long a worker with one test left of a file under way may be held for want of cores (s).
#: pytest-xdist runs a worker's last test only once it knows the next one; a file given then starts
#: when that test ends, whatever the others run by then. Held, the file's robot stack or browser
#: idles: longer holds keep the budget better (bench/schedule_replay.py) and waste more.
LAST_TEST_HELD_S = 600.0

#: The share of the budget a file heavier than that needs free to start.
HEAVIEST_NEED = 0.75
#: How often held workers are looked at again when no test ends (s).
RETRY_HELD_S = 10.0

_SLOW_MARK = re.compile(r"mark\.slow\b(?:\(\s*seconds\s*=\s*(\d+(?:\.\d*)?)\s*\))?")


@dataclass(frozen=True)
class FileCost:
    """What running one test file takes: wall seconds, and the share of a core its processes use."""

    seconds: float
    cores: float = 1.0


@cache
def _measured(costs: Path) -> dict[str, FileCost]:
    try:
        data = json.loads(costs.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return {}
    return {name: FileCost(float(cost["seconds"]), float(cost["cores"])) for name, cost in data.items()}


@cache
def file_cost(path: Path, root: Path) -> FileCost:
    """The measured cost of test file ``path`` (relative to the repository ``root``) or, not measured,
    the seconds its ``pytest.mark.slow(seconds=N)`` states (:data:`SLOW_DEFAULT_S` for a bare
    ``slow``, :data:`QUICK_S` for none) at a whole core."""
    measured = _measured(root / COSTS).get(path.relative_to(root).as_posix()) if path.is_relative_to(root) else None
    if measured is not None:
        return measured
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        return FileCost(QUICK_S)
    found = _SLOW_MARK.search(text)
    if found is None:
        return FileCost(QUICK_S)
    return FileCost(float(found.group(1)) if found.group(1) else SLOW_DEFAULT_S)


def longest_files_first(items: list[pytest.Item], root: Path) -> None:
    """Order ``items`` by file, the longest file first, each file's tests in their own order."""
    files: dict[Path, list[pytest.Item]] = {}
    for item in items:
        files.setdefault(item.path, []).append(item)
    longest = sorted(files, key=lambda path: -file_cost(path, root).seconds)  # stable
    items[:] = [item for path in longest for item in files[path]]


class CostAwareFileScheduling(LoadFileScheduling):  # type: ignore[misc]  # an untyped base
    """Whole files, longest first, to the worker free first, within :data:`CORE_BUDGET`.

    The work queue arrives longest first (the workers collect in that order: tests/conftest.py).
    """

    #: The cores the running files may sum to (bench/schedule_replay.py replays other budgets).
    budget: float = CORE_BUDGET

    def __init__(self, config: pytest.Config, log: Producer | None = None) -> None:
        super().__init__(config, log)
        self._root = Path(config.rootpath)
        self.clock: Callable[[], float] = time.monotonic  # a replay's own clock (bench/schedule_replay.py)
        self._free_at: dict[WorkerController, float] = {}
        self._held: dict[WorkerController, float] = {}  # since when, in the order they were held

    def _cost(self, scope: str) -> FileCost:
        return file_cost(self._root / scope, self._root)

    def _may_hold(self, node: WorkerController, now: float) -> bool:
        """Whether ``node`` may be given nothing for now: it has no file under way (what it has left
        is files of one test, none started), or two tests or more to run (it runs one and keeps the
        other back, and is asked again when the one ends), or, with one test left of a file under
        way, for at most :data:`LAST_TEST_HELD_S`: that test waits, the file's robot stack or browser
        alive, for cores to free. Given a file instead, that file would start unchecked."""
        work = self.assigned_work.get(node, {})
        unfinished = [tests for tests in work.values() if not all(tests.values())]
        if all(len(tests) == 1 for tests in unfinished) or self._pending_of(work) >= 2:
            return True
        return now - self._held.get(node, now) < LAST_TEST_HELD_S

    def _running_a_test(self, node: WorkerController) -> bool:
        """Whether ``node`` runs a test now: a held worker with one test left waits to run it."""
        return node not in self._held or self._pending_of(self.assigned_work.get(node, {})) >= 2

    def _occupied(self, free: dict[WorkerController, float]) -> list[tuple[float, float]]:
        """The cores each of the workers in ``free`` (each with when it will be free) holds, and
        until when: the larger of the file it runs and a file queued behind it (given early, as
        pytest-xdist needs, it starts with no check of its own: counted from the moment it is given,
        so two workers are never handed the same room)."""
        held = []
        for node, free_at in free.items():
            work = self.assigned_work.get(node, {})
            unfinished = [scope for scope, tests in work.items() if not all(tests.values())]
            if unfinished and self._running_a_test(node):
                held.append((max(self._cost(scope).cores for scope in unfinished), free_at))
        return held

    def _free_from(self, node: WorkerController, now: float) -> float:
        """When ``node`` will be free, as best known now. Once its running file has finished some of
        its tests, what is left of it is the share of its cost its other tests stand for, and the
        files queued behind it their whole cost: measured costs go stale (a file that got faster
        would otherwise keep its worker on the shortest files until its old length had passed, while
        the long files wait for the end). Before that, the estimate made when its files were given;
        once that has passed with no test of them ended, when it will be free is unknown (infinite),
        not now: a reservation counted on it would keep nothing back."""
        unfinished = [
            (scope, tests) for scope, tests in self.assigned_work.get(node, {}).items() if not all(tests.values())
        ]
        if not unfinished:
            return now
        if not any(unfinished[0][1].values()):
            estimate = self._free_at.get(node, now)
            return estimate if estimate > now else float("inf")
        (running, tests), *queued = unfinished
        left = len(tests) - sum(tests.values())
        return (
            now
            + self._cost(running).seconds * left / len(tests)
            + sum(self._cost(scope).seconds for scope, _ in queued)
        )

    def _choose(self, node: WorkerController, free_at: float, now: float) -> str | None:
        """The file ``node`` runs next, or None: hold it until a test ends elsewhere.

        The longest file left goes first, to the worker free first, when its cores fit. When they do
        not, it gets a reservation, as a batch system's backfilling does: the time the running files
        will have freed its cores. Until then a worker may only take a file that fits now and ends
        before that time (the longest such), so lighter files never keep a heavy one waiting to the
        end of the run, where the heavy files left would otherwise all run together.
        """
        free = {other: self._free_from(other, now) for other in self.assigned_work if other is not node}
        occupied = self._occupied(free)
        room = self.budget - sum(cores for cores, _ in occupied)
        head = next(iter(self.workqueue))
        need = self._need(head)
        reserved = float("inf") if need <= room else self._reservation(need, room, occupied)
        allowed = [
            scope
            for scope in self.workqueue
            if self._need(scope) <= room and free_at + self._cost(scope).seconds <= reserved
        ]
        others = [until for other, until in free.items() if other in self._free_at and not other.shutting_down]
        if others and free_at > min(others):
            # busy longer than another worker: the longest file is the other's; this one the shortest
            chosen = min(allowed, key=lambda scope: self._cost(scope).seconds, default=None)
        else:
            chosen = next(iter(allowed), None)  # the longest allowed: the head itself when it fits
        if chosen is not None:
            return str(chosen)
        if self._may_hold(node, now) and occupied:
            return None
        # nor is a worker alone held: the file of least CPU (a quick file defers the choice to its end)
        return str(min(self.workqueue, key=lambda scope: self._cost(scope).cores * self._cost(scope).seconds))

    def _need(self, scope: str) -> float:
        """The cores a file needs free to start: one heavier than :data:`HEAVIEST_NEED` of the budget
        starts once that much is free (beside files that mostly wait: a budget it can never have
        would keep it to the run's end)."""
        return min(self._cost(scope).cores, HEAVIEST_NEED * self.budget)

    @staticmethod
    def _reservation(need: float, room: float, occupied: list[tuple[float, float]]) -> float:
        """When the running files, ending as estimated, will have freed ``need`` cores beside ``room``."""
        reserved = 0.0
        for cores, until in sorted(occupied, key=lambda pair: pair[1]):
            if room >= need:
                break
            room, reserved = room + cores, until
        return reserved

    def _assign_work_unit(self, node: WorkerController) -> None:
        now = self.clock()
        free_at = self._free_from(node, now)
        scope = self._choose(node, free_at, now)
        if scope is None:
            if self._pending_of(self.assigned_work.get(node, {})) >= 2:
                self._held[node] = now  # a test still runs: the hold's limit counts from the last one
            else:
                self._held.setdefault(node, now)
            return
        self._held.pop(node, None)
        work_unit = self.workqueue.pop(scope)
        self._free_at[node] = free_at + self._cost(scope).seconds
        self.assigned_work.setdefault(node, {})[scope] = work_unit
        collection = self.registered_collections[node]
        node.send_runtest_some([collection.index(nodeid) for nodeid, done in work_unit.items() if not done])

    def mark_test_complete(self, node: WorkerController, item_index: int, duration: float = 0) -> None:
        """A test ended: its worker may get its next file, and so may the workers held for want of cores."""
        super().mark_test_complete(node, item_index, duration)
        self._retry_held(besides=node)

    def _retry_held(self, besides: WorkerController | None = None) -> None:
        for held in list(self._held):
            if held is not besides:
                self._reschedule(held)

    def retry_held_every(self, seconds: float, controller: Any) -> threading.Event:
        """Look at the held workers again every ``seconds`` as well, not only when a test ends: with
        one ten-minute test running elsewhere, they would be held for its length, whatever
        :data:`LAST_TEST_HELD_S` says. ``controller`` is pytest-xdist's DSession, which handles its
        workers' events one at a time in its own thread: the retry is put among them as an event of
        its own, so it never runs beside another. Returns the event that stops it."""
        controller.worker_retry_held = self._retry_held
        stop = threading.Event()

        def tick() -> None:
            while not stop.wait(seconds):
                controller.queue.put(("retry_held", {}))

        threading.Thread(target=tick, name="retry-held-workers", daemon=True).start()
        return stop

    def remove_node(self, node: WorkerController) -> str | None:
        self._held.pop(node, None)
        return super().remove_node(node)  # type: ignore[no-any-return]  # an untyped base
