"""Fixtures of the PAX suite: the real rosbridge server and the real IVA robot stack.

tests/pax/conftest.py registers these fixtures for the PAX suite.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from caretaker.stack import Stack
from support.stack import robot_parts

REPO = Path(__file__).resolve().parents[2]
BINDINGS = REPO / "sysrep" / "bindings"


@pytest.fixture(scope="module")
def ros_env_module() -> dict[str, str]:
    return dict(os.environ)


@pytest.fixture(scope="module")
def stack(ros_env_module: dict[str, str]) -> Iterator[Stack]:
    """The IVA deployment's rosbridge (on a free port: ``stack.bridge_url``), simulation, planner
    and AT server (no command ledger); ``stack.start_part("at-server")`` restarts the AT server
    after a test killed it."""
    # Time scale 4: executions take a quarter of real time; nothing here observes "while moving".
    # No command ledger: these tests drive the plugins' direct path (a loopback binding on a habitat
    # without a ledger); the ledger path is tested in tests/ledger and tests/flight.
    with robot_parts("iva", ros_env_module, time_scale=4.0, parts=["sim", "planner", "at-server", "bridge"]) as stack:
        yield stack
