"""Test-session settings shared by every suite.

ROS 2 traffic stays on loopback and in a domain of this session's own (claimed with a lock, see
support/ros_domain.py; each pytest-xdist worker claims its own), so parallel test runs on one
machine do not see each other. One
PostgreSQL server serves every suite of the session that needs one (support/postgres.py).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

import pytest

from support.file_schedule import RETRY_HELD_S, CostAwareFileScheduling, longest_files_first
from support.postgres import PostgresServer, postgres_server
from support.processes import ManagedProcess, caretaker
from support.ros_domain import claim_ros_domain

if TYPE_CHECKING:  # playwright is loaded only by sessions with browser tests
    from playwright.sync_api import Browser, Playwright
    from xdist.remote import Producer  # type: ignore[import-untyped]

    from support.browser import SharedChromium

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
# pytest-xdist workers inherit the controller's environment: each claims a domain of its own.
if "ROS_DOMAIN_ID" not in os.environ or "PYTEST_XDIST_WORKER" in os.environ:
    os.environ["ROS_DOMAIN_ID"] = str(claim_ros_domain())
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest test files first, each file's tests in their own order.

    pytest-xdist hands whole files to its workers in collection order (``make test`` turns off its
    own reordering by test count, and :func:`pytest_xdist_make_scheduler` picks from this order): a
    file that takes ten minutes started last would end the suite ten minutes late; started first,
    it runs beside everything else. What each file takes is measured (tests/file_costs.json, by
    bench/suite_profile.py --save-costs); a new file states it with ``pytest.mark.slow(seconds=N)``.
    """
    longest_files_first(items, config.rootpath)


@pytest.hookimpl(optionalhook=True)  # only where pytest-xdist runs the session
def pytest_xdist_make_scheduler(config: pytest.Config, log: Producer) -> CostAwareFileScheduling:
    """Whole files to workers, none queued behind a long one, within the cores (support/file_schedule.py)."""
    scheduler = CostAwareFileScheduling(config, log)
    scheduler.retry_held_every(RETRY_HELD_S, config.pluginmanager.getplugin("dsession"))
    return scheduler


@pytest.fixture(scope="session")
def ros_env() -> dict[str, str]:
    """Environment for child processes: this session's ROS domain, loopback only."""
    return dict(os.environ)


@pytest.fixture(scope="session")
def postgres() -> Iterator[PostgresServer]:
    """This session's PostgreSQL server, shared by every suite (started on first use, removed at the end).

    It never fsyncs (nor does its initdb): the tests kill processes, never the machine, and on a
    crowded machine a cluster's initdb ran past its minute."""
    with postgres_server(settings={"fsync": "off"}) as server:
        yield server


@pytest.fixture(scope="module")
def playwright() -> Iterator[Playwright]:
    """One Playwright driver per test module.

    Its sync API keeps an asyncio loop marked running on the main thread while it lives, so a
    session-wide driver would break every later test that calls ``asyncio.run``.
    """
    from playwright.sync_api import sync_playwright  # only sessions with browser tests load it

    with sync_playwright() as driver:
        yield driver


@pytest.fixture(scope="session")
def chromium() -> Iterator[dict[str, SharedChromium]]:
    """This worker's Chromiums by kind, "plain" and "webgl" (support/browser.py SharedChromium),
    each started on first use and stopped at the end."""
    from support.browser import CHROMIUM_ARGS, WEBGL_ARGS, SharedChromium

    kinds = {"plain": SharedChromium(CHROMIUM_ARGS), "webgl": SharedChromium(WEBGL_ARGS)}
    yield kinds
    for shared in kinds.values():
        shared.close()


@pytest.fixture(scope="module")
def browser(playwright: Playwright, chromium: dict[str, SharedChromium]) -> Iterator[Browser]:
    """Debian's Chromium, headless: this worker's, connected for this module (the contexts it
    opened end with the module's driver)."""
    yield chromium["plain"].connect(playwright)


@pytest.fixture
def launch(ros_env: dict[str, str]) -> Iterator[Callable[..., ManagedProcess]]:
    """Start single ``caretaker`` parts (a whole robot side starts through support/stack.py).

    ``launch("ledger", "--state-dir", DIR)`` returns the process once it printed READY; every one
    started is stopped at teardown.
    """
    started: list[ManagedProcess] = []

    def start(*args: str, ready_timeout: float = 90.0, wait: bool = True) -> ManagedProcess:
        proc = caretaker(*args, env=ros_env)
        started.append(proc)
        if wait:
            proc.wait_ready(ready_timeout)
        return proc

    yield start
    for proc in reversed(started):
        proc.stop()
