"""Waiting on a run of the procedure executive: until it holds, or until it ended."""

from __future__ import annotations

from pride.executive import Executive, Hold, RunStatus, Snapshot

__all__ = ["TIMEOUT", "finished", "held"]

TIMEOUT = 20.0


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
