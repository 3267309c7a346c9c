"""The suite's own scheduling (support/file_schedule.py): no file behind a long one, cores respected.

Small suites in a temporary folder, run by real pytest-xdist: a long file whose test waits until
other files have run. pytest-xdist's own scheduling queues a file on the long file's worker, behind
it, so the long test waits in vain; :class:`CostAwareFileScheduling` gives that worker the
shortest file instead. And two files that each keep two cores busy never run at once: lighter
files run beside them, or the worker waits.
"""

from __future__ import annotations

import json
import queue
import time
import types
from collections import OrderedDict
from pathlib import Path

import pytest

from support.file_schedule import (
    CORE_BUDGET,
    COSTS,
    LAST_TEST_HELD_S,
    QUICK_S,
    SLOW_DEFAULT_S,
    CostAwareFileScheduling,
    FileCost,
    file_cost,
)

pytest_plugins = ["pytester"]
pytestmark = pytest.mark.slow(seconds=30)  # three small suites, each starting pytest-xdist workers

TESTS = Path(__file__).resolve().parents[1]
#: A file one of which fits the core budget and two do not, and one that fits beside it.
HEAVY, LIGHT = 0.6 * CORE_BUDGET, 0.1 * CORE_BUDGET

CONFTEST = """
import os
import pytest
from support.file_schedule import RETRY_HELD_S, CostAwareFileScheduling, longest_files_first

def pytest_collection_modifyitems(config, items):
    longest_files_first(items, config.rootpath)

if os.environ.get("SCHEDULE") == "ours":
    @pytest.hookimpl(optionalhook=True)
    def pytest_xdist_make_scheduler(config, log):
        scheduler = CostAwareFileScheduling(config, log)
        scheduler.retry_held_every(RETRY_HELD_S, config.pluginmanager.getplugin("dsession"))
        return scheduler
"""

#: The first test of a file: it waits (a bounded time) until the files named in $WAIT_FOR have run,
#: and fails if a file named in $NOT_BESIDE started meanwhile.
WAITING = """
import os, pathlib, time

def test_waiting(request):
    done = pathlib.Path(os.environ["DONE"])
    (done / ("started " + request.node.path.name)).touch()
    wanted = {"done " + name for name in os.environ["WAIT_FOR"].split()}
    deadline = time.monotonic() + float(os.environ["PATIENCE"])
    while not wanted <= {p.name for p in done.iterdir()} and time.monotonic() < deadline:
        time.sleep(0.05)  # polling a folder other processes write: there is no event to wait on
    seen = {p.name for p in done.iterdir()}
    assert wanted <= seen, f"never ran beside this file: {sorted(wanted - seen)}"
    beside = {"started " + name for name in os.environ.get("NOT_BESIDE", "").split()} & seen
    assert not beside, f"ran beside this file: {sorted(beside)}"
"""

MARKING = """
import os, pathlib

def test_marking(request):
    done = pathlib.Path(os.environ["DONE"])
    (done / ("started " + request.node.path.name)).touch()
    (done / ("done " + request.node.path.name)).touch()
"""


def run_suite(
    pytester: pytest.Pytester,
    monkeypatch: pytest.MonkeyPatch,
    *,
    files: dict[str, str],
    costs: dict[str, FileCost],
    schedule: str,
    patience: float,
    wait_for: str,
    not_beside: str = "",
    workers: int = 2,
) -> pytest.RunResult:
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(**files)
    (pytester.path / COSTS).parent.mkdir(parents=True, exist_ok=True)
    (pytester.path / COSTS).write_text(json.dumps({f"{name}.py": vars(cost) for name, cost in costs.items()}))
    done = pytester.mkdir("done")
    for name, value in {
        "PYTHONPATH": str(TESTS),
        "DONE": str(done),
        "PATIENCE": str(patience),
        "SCHEDULE": schedule,
        "WAIT_FOR": wait_for,
        "NOT_BESIDE": not_beside,
        "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1",  # xdist alone (-p below): each worker starts in a fraction
    }.items():
        monkeypatch.setenv(name, value)
    return pytester.runpytest_subprocess(
        "-p", "xdist", "-n", str(workers), "--dist", "loadfile", "--no-loadscope-reorder", "-p", "no:cacheprovider"
    )


def behind_the_long_one(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch, schedule: str) -> pytest.RunResult:
    """One long file waiting for three mediums; one quick file."""
    return run_suite(
        pytester,
        monkeypatch,
        files={"test_long": WAITING, "test_m1": MARKING, "test_m2": MARKING, "test_m3": MARKING, "test_q": MARKING},
        costs={"test_long": FileCost(100, 0.2), **{f"test_m{i}": FileCost(10, 0.2) for i in (1, 2, 3)}},
        schedule=schedule,
        patience=120 if schedule == "ours" else 3,
        wait_for="test_m1.py test_m2.py test_m3.py",
    )


def test_no_file_waits_behind_the_long_one(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> None:
    behind_the_long_one(pytester, monkeypatch, "ours").assert_outcomes(passed=5)


def test_pytest_xdist_alone_queues_a_file_behind_the_long_one(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The behaviour the scheduler exists for: without it the long test's wait is in vain."""
    behind_the_long_one(pytester, monkeypatch, "xdist").assert_outcomes(passed=4, failed=1)


def test_two_files_of_two_cores_never_run_at_once_while_lighter_ones_wait(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three workers; the heavy long file waits until both light files ran beside it, and the other
    heavy file (two do not fit the core budget) may not have started meanwhile (it is longer than
    the light ones: in plain order it would go first)."""
    run_suite(
        pytester,
        monkeypatch,
        files={"test_heavy_a": WAITING, "test_heavy_b": MARKING, "test_light1": MARKING, "test_light2": MARKING},
        costs={
            "test_heavy_a": FileCost(100, HEAVY),
            "test_heavy_b": FileCost(50, HEAVY),
            "test_light1": FileCost(20, LIGHT),
            "test_light2": FileCost(20, LIGHT),
        },
        schedule="ours",
        patience=120,
        wait_for="test_light1.py test_light2.py",
        not_beside="test_heavy_b.py",
        workers=3,
    ).assert_outcomes(passed=4)


def test_a_worker_is_held_rather_than_run_a_file_the_cores_cannot_carry(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three workers, two heavy files and one light one: the third worker has nothing that fits
    beside the first heavy file, so it waits (the second heavy file runs after the first, never
    beside it), where plain cost order would have run both heavy files at once."""
    run_suite(
        pytester,
        monkeypatch,
        files={"test_heavy_a": WAITING, "test_heavy_b": MARKING, "test_light": MARKING},
        costs={
            "test_heavy_a": FileCost(100, HEAVY),
            "test_heavy_b": FileCost(50, HEAVY),
            "test_light": FileCost(20, LIGHT),
        },
        schedule="ours",
        patience=120,
        wait_for="test_light.py",
        not_beside="test_heavy_b.py",
        workers=3,
    ).assert_outcomes(passed=3)


def test_a_file_costs_what_was_measured_or_what_its_mark_declares(tmp_path: Path) -> None:
    (tmp_path / COSTS).parent.mkdir(parents=True)
    (tmp_path / COSTS).write_text(json.dumps({"m.py": {"seconds": 12.5, "cores": 0.3}}))
    cases = {
        "m.py": ("pytestmark = pytest.mark.slow(seconds=240)", FileCost(12.5, 0.3)),
        "a.py": ("pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=240)]", FileCost(240.0)),
        "b.py": ("pytestmark = pytest.mark.slow", FileCost(SLOW_DEFAULT_S)),
        "c.py": ("def test(): pass", FileCost(QUICK_S)),
    }
    for name, (text, cost) in cases.items():
        (tmp_path / name).write_text(text)
        assert file_cost(tmp_path / name, tmp_path) == cost, name
    assert file_cost(tmp_path / "missing.py", tmp_path) == FileCost(QUICK_S)


class Worker:
    """A stand-in for pytest-xdist's WorkerController: what the scheduler reads of one."""

    shutting_down = False


def test_a_worker_whose_file_ran_faster_than_measured_gets_the_longest_file_left(pytester: pytest.Pytester) -> None:
    """A file measured at 100 s has run three of its four tests at once: its worker is nearly free,
    sooner than the other worker's 50 s file, so it gets the longest file left, not the shortest
    (by the stale measure it would be busy longer, and the long file would wait for the end). The
    workers are stand-ins: this is the scheduler's own arithmetic."""
    costs = {"busy.py": FileCost(50, 0.2), "stale.py": FileCost(100, 0.2), "long.py": FileCost(40, 0.2)}
    (pytester.path / COSTS).parent.mkdir(parents=True, exist_ok=True)
    (pytester.path / COSTS).write_text(json.dumps({name: vars(cost) for name, cost in costs.items()}))
    scheduler = CostAwareFileScheduling(pytester.parseconfig("-p", "xdist", "--tx", "2*popen"))
    busy, fast = Worker(), Worker()
    now = time.monotonic()
    scheduler._free_at = {busy: now + 50, fast: now + 100}
    scheduler.assigned_work = {
        busy: {"busy.py": {"busy.py::test": False}},
        fast: {"stale.py": {f"stale.py::test_{i}": i < 3 for i in range(4)}},
    }
    scheduler.workqueue = OrderedDict([("long.py", {"long.py::test": False}), ("quick.py", {"quick.py::test": False})])
    free_at = scheduler._free_from(fast, now)
    assert free_at == pytest.approx(now + 25)
    assert scheduler._choose(fast, free_at, now) == "long.py"
    # none of its tests finished yet: the estimate made when it was given stands
    scheduler.assigned_work[fast] = {"stale.py": {f"stale.py::test_{i}": False for i in range(4)}}
    assert scheduler._choose(fast, scheduler._free_from(fast, now), now) == "quick.py"


def test_a_heavy_file_that_does_not_fit_is_reserved_the_cores_the_running_file_frees(
    pytester: pytest.Pytester,
) -> None:
    """A heavy file runs for 100 s more; the next heavy file does not fit beside it, so it is
    reserved the moment the first ends. A free worker may take a light file that ends before that
    (30 s), not one that would still run then (150 s): with nothing else it is held. The old rule,
    the first file that fits, gave it the 150 s file, and the light files kept the heavy ones to the
    end of the run. Stand-in workers: this is the scheduler's own arithmetic."""
    costs = {
        "running.py": FileCost(100, HEAVY),
        "heavy.py": FileCost(80, HEAVY),
        "long_light.py": FileCost(150, LIGHT),
        "short_light.py": FileCost(30, LIGHT),
    }
    (pytester.path / COSTS).parent.mkdir(parents=True, exist_ok=True)
    (pytester.path / COSTS).write_text(json.dumps({name: vars(cost) for name, cost in costs.items()}))
    scheduler = CostAwareFileScheduling(pytester.parseconfig("-p", "xdist", "--tx", "2*popen"))
    busy, free = Worker(), Worker()
    now = time.monotonic()
    scheduler._free_at = {busy: now + 100, free: now}
    scheduler.assigned_work = {busy: {"running.py": {"running.py::test": False}}}
    queue = [(name, {f"{name}::test": False}) for name in ("heavy.py", "long_light.py", "short_light.py")]
    scheduler.workqueue = OrderedDict(queue)
    assert scheduler._choose(free, now, now) == "short_light.py"
    del scheduler.workqueue["short_light.py"]
    assert scheduler._choose(free, now, now) is None
    # once the heavy file ran out its time, the next heavy file is the one that fits
    scheduler.assigned_work[busy]["running.py"]["running.py::test"] = True
    assert scheduler._choose(free, now, now) == "heavy.py"


def test_a_worker_with_one_test_left_is_held_for_cores_only_so_long(pytester: pytest.Pytester) -> None:
    """A worker whose file has one test left (pytest-xdist keeps it back until the next file is
    known) is held while nothing fits beside the heavy file running elsewhere, as a worker between
    files is; past LAST_TEST_HELD_S it gets the file of least CPU, so that test does not wait on,
    its file's stack alive, for as long as the heavy file runs."""
    costs = {
        "running.py": FileCost(600, HEAVY),
        "heavy.py": FileCost(80, HEAVY),
        "waiting.py": FileCost(300, 0.05),
        "mine.py": FileCost(30, LIGHT),
    }
    (pytester.path / COSTS).parent.mkdir(parents=True, exist_ok=True)
    (pytester.path / COSTS).write_text(json.dumps({name: vars(cost) for name, cost in costs.items()}))
    scheduler = CostAwareFileScheduling(pytester.parseconfig("-p", "xdist", "--tx", "2*popen"))
    scheduler.budget = HEAVY + 0.01  # nothing fits beside the running heavy file
    busy, mine = Worker(), Worker()
    now = time.monotonic()
    scheduler._free_at = {busy: now + 600, mine: now}
    scheduler.assigned_work = {
        busy: {"running.py": {"running.py::test": False}},
        mine: {"mine.py": {f"mine.py::test_{i}": i < 2 for i in range(3)}},
    }
    scheduler.workqueue = OrderedDict((name, {f"{name}::test": False}) for name in ("heavy.py", "waiting.py"))
    scheduler._held[mine] = now - 10
    assert scheduler._choose(mine, now, now) is None
    scheduler._held[mine] = now - LAST_TEST_HELD_S - 1
    assert scheduler._choose(mine, now, now) == "waiting.py"  # 15 CPU-s, against the heavy file's 60


def test_the_hold_limit_counts_from_when_the_worker_is_left_with_its_last_test(pytester: pytest.Pytester) -> None:
    """Held with two tests left, a worker still runs one: its LAST_TEST_HELD_S counts from its last
    hold with two left (a test ended, or the retry ran, at most RETRY_HELD_S before its last test
    began), not from its first hold, which a long test before would have used up."""
    costs = {"running.py": FileCost(900, HEAVY), "heavy.py": FileCost(80, HEAVY), "mine.py": FileCost(30, LIGHT)}
    (pytester.path / COSTS).parent.mkdir(parents=True, exist_ok=True)
    (pytester.path / COSTS).write_text(json.dumps({name: vars(cost) for name, cost in costs.items()}))
    scheduler = CostAwareFileScheduling(pytester.parseconfig("-p", "xdist", "--tx", "2*popen"))
    scheduler.budget = HEAVY + 0.01  # nothing fits beside the running heavy file
    busy, mine = Worker(), Worker()
    clock = [1000.0]
    scheduler.clock = lambda: clock[0]
    scheduler._free_at = {busy: 1900.0, mine: 1000.0}
    scheduler.assigned_work = {
        busy: {"running.py": {"running.py::test": False}},
        mine: {"mine.py": {f"mine.py::test_{i}": i < 1 for i in range(3)}},
    }
    scheduler.workqueue = OrderedDict([("heavy.py", {"heavy.py::test": False})])
    scheduler._assign_work_unit(mine)
    clock[0] += LAST_TEST_HELD_S + 100  # its test ran long: two are still left
    scheduler._assign_work_unit(mine)
    assert scheduler._held[mine] == clock[0]
    scheduler.assigned_work[mine]["mine.py"]["mine.py::test_1"] = True
    clock[0] += 10
    scheduler._assign_work_unit(mine)  # now blocked on its last test: held, its limit starts here
    assert scheduler._held[mine] == clock[0] - 10
    assert "heavy.py" in scheduler.workqueue


def test_held_workers_are_looked_at_again_on_the_controllers_thread_while_no_test_ends(
    pytester: pytest.Pytester,
) -> None:
    """The retry goes into pytest-xdist's event queue as an event of its own, which its DSession
    dispatches to ``worker_retry_held`` on its thread; and once the file a reservation waited for
    outran its estimate, the reservation no longer keeps a light file back. Stand-ins: the
    controller is a queue, as DSession's is."""
    (pytester.path / COSTS).parent.mkdir(parents=True, exist_ok=True)
    costs = {"running.py": FileCost(100, HEAVY), "heavy.py": FileCost(80, HEAVY), "light.py": FileCost(150, LIGHT)}
    (pytester.path / COSTS).write_text(json.dumps({name: vars(cost) for name, cost in costs.items()}))
    scheduler = CostAwareFileScheduling(pytester.parseconfig("-p", "xdist", "--tx", "2*popen"))
    controller = types.SimpleNamespace(queue=queue.Queue())
    stop = scheduler.retry_held_every(0.01, controller)
    try:
        assert controller.queue.get(timeout=60) == ("retry_held", {})
    finally:
        stop.set()
    assert controller.worker_retry_held == scheduler._retry_held
    busy, free = Worker(), Worker()
    now = time.monotonic()
    scheduler.assigned_work = {busy: {"running.py": {"running.py::test": False}}}
    scheduler.workqueue = OrderedDict((name, {f"{name}::test": False}) for name in ("heavy.py", "light.py"))
    scheduler._free_at = {busy: now + 100, free: now}
    assert scheduler._choose(free, now, now) is None  # the light file would end after the reservation
    scheduler._free_at[busy] = now - 1  # the running file outran its estimate
    assert scheduler._choose(free, now, now) == "light.py"
