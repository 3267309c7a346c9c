"""Fixtures of the PAX suite: the real rosbridge server and the real IVA robot stack.

Test modules import these fixtures by name. The suite has no conftest.py on purpose: other
suites do ``from conftest import ...``, and a second directory-level conftest module would
shadow theirs when both directories are collected in one run.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from support.processes import ManagedProcess, caretaker

REPO = Path(__file__).resolve().parents[2]
BINDINGS = REPO / "sysrep" / "bindings"


def bridge_url(bridge: ManagedProcess) -> str:
    """The ws:// URL from the bridge's ``READY bridge ws://HOST:PORT`` line."""
    line = next(line for line in bridge.output if line.startswith("READY bridge "))
    return line.split()[-1]


class Stack:
    """The IVA robot's processes; ``restart_at_server`` replaces one, teardown stops all."""

    def __init__(self, env: dict[str, str]) -> None:
        self.env = env
        self.processes: dict[str, ManagedProcess] = {}

    def start(self, name: str, *args: str) -> ManagedProcess:
        process = caretaker(*args, env=self.env, name=name)
        self.processes[name] = process
        return process

    def start_at_server(self) -> ManagedProcess:
        process = self.start("at-server", "at-server", "--robot", "ur10")
        process.wait_ready(90.0)
        return process

    def stop(self) -> None:
        for process in reversed(list(self.processes.values())):
            process.stop()


@pytest.fixture(scope="module")
def ros_env_module() -> dict[str, str]:
    return dict(os.environ)


@pytest.fixture(scope="module")
def stack(ros_env_module: dict[str, str]) -> Iterator[Stack]:
    """rosbridge (`caretaker bridge --port 0`), simulation, planner and AT server of the IVA robot."""
    stack = Stack(ros_env_module)
    try:
        stack.start("bridge", "bridge", "--port", "0")
        # Time scale 4: executions take a quarter of real time; nothing here observes "while moving".
        stack.start("sim", "sim", "--scene", "iva", "--time-scale", "4")
        stack.start("planner", "planner", "--robot", "ur10")
        stack.start("at-server", "at-server", "--robot", "ur10")
        for process in list(stack.processes.values()):
            process.wait_ready(90.0)
        yield stack
    finally:
        stack.stop()
