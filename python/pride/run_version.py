"""The version of a procedure a run runs, as its ``run_started`` records it.

A plain record so the executive can carry it without the ground database: which versions may
run is decided from the release history (:func:`records.releases.version_for_run`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["RunVersion"]


@dataclass(frozen=True)
class RunVersion:
    """The version a run runs: its hash, its release (None: a rehearsal of a draft or of a changed file)."""

    sha256: str
    release: int | None
    rehearsal: bool

    def data(self) -> dict[str, Any]:
        """What ``run_started`` records of it."""
        return {"sha256": self.sha256, "release": self.release, "rehearsal": self.rehearsal}
