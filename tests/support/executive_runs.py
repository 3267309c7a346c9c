"""Waiting on a run of the procedure executive: until it holds, or until it ended."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeAlias

from pride.executive import Executive, Hold, RunStatus, Snapshot
from support.audit import RecordedJournal
from support.lab_gateway import LabGateway

__all__ = ["TIMEOUT", "Bench", "finished", "held"]

TIMEOUT = 20.0

#: The ``bench`` fixture of tests/pride/conftest.py: ``bench(mode, name, gateway, run_id=, control=,
#: journal=)`` makes an executive on the lab bench and returns it with its gateway and journal.
Bench: TypeAlias = Callable[..., tuple[Executive, LabGateway, RecordedJournal]]


def held(executive: Executive, hold: Hold, at: str) -> Snapshot:
    """The run's snapshot once it holds; it must hold with ``hold`` at ``at``."""
    snap = executive.wait_for(lambda s: s.hold is not None or s.status is not RunStatus.ACTIVE, TIMEOUT)
    assert snap is not None, "the run neither held nor ended"
    assert (snap.hold, snap.current) == (hold, at), snap
    return snap


def finished(executive: Executive) -> Snapshot:
    snap = executive.wait_for(lambda s: s.status is not RunStatus.ACTIVE, TIMEOUT)
    assert snap is not None
    return snap
