"""Test-session settings shared by every suite.

ROS 2 traffic stays on loopback and in a domain of this session's own (claimed with a lock, see
support/ros_domain.py), so parallel test runs on one machine do not see each other.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator

import pytest

from support.processes import ManagedProcess, caretaker
from support.ros_domain import claim_ros_domain

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
if "ROS_DOMAIN_ID" not in os.environ:
    os.environ["ROS_DOMAIN_ID"] = str(claim_ros_domain())
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")


@pytest.fixture(scope="session")
def ros_env() -> dict[str, str]:
    """Environment for child processes: this session's ROS domain, loopback only."""
    return dict(os.environ)


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
