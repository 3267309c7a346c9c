"""Test-only delay hooks: hold a robot-side process at a named point, so a test can put a halt there.

``CARETAKER_TEST_DELAY_HOOKS="ledger.forward=2,at_server.send_goal=2,sim.gripper=2"`` holds every
pass of each named point for that many seconds (the points: :data:`POINTS`). Each hold is logged
before it begins (``test delay hook ledger.forward: holding 2 s``), so a test waits for that line,
not for a time, and then sends its halt into the gap.

Read only in a test build: a source checkout, where the tests sit beside the code. An installed
Caretaker ignores the variable and says so once; a robot never waits for a test.
"""

from __future__ import annotations

import logging
import math
import os
import threading
from functools import cache
from pathlib import Path

__all__ = ["ENVIRONMENT", "POINTS", "pause"]

LOG = logging.getLogger(__name__)

ENVIRONMENT = "CARETAKER_TEST_DELAY_HOOKS"
#: The points a test may hold, and where they are.
POINTS = {
    "ledger.forward": "the command ledger, after it took a command and before it calls the service",
    "at_server.send_goal": "the AT server, after it took an execution and before it sends a trajectory goal",
    "sim.gripper": "the simulation's gripper service, after a request arrived and before the fingers start",
}
#: The checkout's test suite: present in a test build only.
_TESTS = Path(__file__).resolve().parents[2] / "tests" / "conftest.py"


def pause(point: str) -> None:
    """Hold here for the seconds the variable gives ``point``; at once without it."""
    seconds = _holds().get(point)
    if seconds:
        LOG.warning("test delay hook %s: holding %g s", point, seconds)
        threading.Event().wait(seconds)  # nothing to wait for: the hold is the point


@cache
def _holds() -> dict[str, float]:
    """The holds the variable asks for; bad entries are logged and left out."""
    text = os.environ.get(ENVIRONMENT, "").strip()
    if not text:
        return {}
    if not _TESTS.is_file():
        LOG.warning("%s is set but ignored: delay hooks exist in a test build (a source checkout) only", ENVIRONMENT)
        return {}
    holds: dict[str, float] = {}
    for entry in filter(None, (e.strip() for e in text.split(","))):
        point, _, value = entry.partition("=")
        try:
            seconds = float(value)
        except ValueError:
            seconds = math.nan
        if point not in POINTS or not math.isfinite(seconds) or not 0 < seconds <= 600:
            LOG.error(
                "%s: %r left out: write POINT=SECONDS (0 < SECONDS <= 600), POINT one of %s",
                ENVIRONMENT,
                entry,
                ", ".join(POINTS),
            )
            continue
        holds[point] = seconds
    if holds:
        LOG.warning("test delay hooks active: %s", ", ".join(f"{p}={s:g} s" for p, s in holds.items()))
    return holds
