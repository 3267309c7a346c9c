"""The suite can fail: Caretaker's bridge behind a proxy with one deliberate fault is FAILED in
exactly the cases that cite the statement the fault breaks, and in no other.

One bridge for the module; the three faulty proxies in front of it, each checked by its own
``caretaker interop`` process, all three at once (every case uses names of its own run).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from interop.catalog import DEFAULT_PROFILES
from support.processes import ManagedProcess, caretaker, python

from .suite_support import assert_complete, citing, finish_suite, start_suite

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=90)]

PROXY = Path(__file__).with_name("faulty_proxy.py")
#: fault -> the statement it breaks
FAULTS = {"drop-status": "P-STAT-2", "drop-last-fragment": "P-FRAG-3", "close-on-unknown-op": "P-ERR-2"}


@pytest.fixture(scope="module")
def bridge(ros_env: dict[str, str]) -> Iterator[str]:
    process = caretaker(
        "bridge", "--port", "0", "--service-timeout", "5", "--node-name", "rosbridge_interop", env=ros_env
    )
    try:
        line = process.wait_ready(60)
        yield line.split()[-1]
    finally:
        process.stop()


@pytest.fixture(scope="module")
def proxies(bridge: str, ros_env: dict[str, str]) -> Iterator[dict[str, str]]:
    started: dict[str, ManagedProcess] = {}
    try:
        for fault in FAULTS:
            started[fault] = python(str(PROXY), "--to", bridge, "--fault", fault, env=ros_env, name=f"proxy-{fault}")
        yield {fault: process.wait_for_line(r"^READY proxy", 30).split()[-1] for fault, process in started.items()}
    finally:
        for process in started.values():
            process.stop()


def test_each_fault_fails_exactly_the_cases_citing_its_statement(
    proxies: dict[str, str], tmp_path: Path, ros_env: dict[str, str]
) -> None:
    runs = {fault: start_suite(url, tmp_path / fault, fault, env=ros_env) for fault, url in proxies.items()}
    finished = {fault: finish_suite(process, tmp_path / fault, fault, timeout=240) for fault, process in runs.items()}
    for fault, run in finished.items():
        assert_complete(run, DEFAULT_PROFILES)
        expected = citing(FAULTS[fault], DEFAULT_PROFILES)
        assert expected, f"no case cites {FAULTS[fault]}"
        assert run.failed() == expected, (
            f"{fault}: FAILED {sorted(run.failed())}, the cases citing {FAULTS[fault]} are {sorted(expected)}\n"
            + "\n".join(line for line in run.output.splitlines() if "FAILED" in line)
        )
        assert run.returncode == 1, run.output[-2000:]
        assert "FAIL" in run.output.splitlines()[-1] or "FAIL" in run.output
