"""The habitat's memory of every unit it answered: a unit is answered once, and that answer stands.

A unit is the ground's order to start one run. Whoever can reach the habitat's bridge can send a
unit again, byte for byte, long after it was answered: its signature still holds and, within its
lifetime, so does its expiry. So the habitat keeps every answer it gave to a signed unit, accepted
or refused, by the unit's hash and by its run id, in an append-only file (``answers.jsonl``): the
same unit again gets the same answer, and a run id that was ever answered never starts a (second)
run, whatever unit names it. A refusal is final too: a unit refused because another run was active
does not start when that run has ended; the ground uplinks a new unit under a new run id.
"""

from __future__ import annotations

import json
import logging
import os
import threading
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

__all__ = ["UnitAnswers", "UplinkAnswer"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class UplinkAnswer:
    """The habitat's answer to a unit (``Uplink.srv``'s response)."""

    state: str  # ACCEPTED | REFUSED | EXPIRED
    unit_hash: str
    run_id: str  # "" when the unit could not be read
    message: str


class UnitAnswers:
    """Every answer given to a signed unit, by unit hash and by run id; kept across restarts. Thread-safe."""

    def __init__(self, path: Path, accepted: Iterable[UplinkAnswer] = ()) -> None:
        """``accepted``: units accepted before this memory existed (their folders under ``units/``),
        remembered as accepted unless the file says otherwise."""
        self._path = path
        self._lock = threading.Lock()  # the two maps and the file
        self._by_hash: dict[str, UplinkAnswer] = {}
        self._by_run: dict[str, UplinkAnswer] = {}
        for answer in accepted:
            self._remember(answer)
        if path.exists():
            for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                try:
                    self._remember(UplinkAnswer(**json.loads(line)))
                except (ValueError, TypeError) as exc:  # a line cut by a crash while it was written
                    log.error("%s:%d: not an answer, left out (%s)", path, number, exc)

    def _remember(self, answer: UplinkAnswer) -> None:
        self._by_hash[answer.unit_hash] = answer
        if answer.run_id:
            self._by_run.setdefault(answer.run_id, answer)  # the first answer for a run id is its answer

    def of_unit(self, unit_hash: str) -> UplinkAnswer | None:
        """The answer given to this very unit, if it was answered."""
        with self._lock:
            return self._by_hash.get(unit_hash)

    def of_run(self, run_id: str) -> UplinkAnswer | None:
        """The first answer given to a unit of this run id, if any was."""
        with self._lock:
            return self._by_run.get(run_id)

    def __len__(self) -> int:
        with self._lock:
            return len(self._by_hash)

    def keep(self, answer: UplinkAnswer) -> None:
        """Remember ``answer`` for good: on disk (flushed and synced) before it is given."""
        with self._lock:
            with self._path.open("a", encoding="utf-8") as file:
                file.write(json.dumps(asdict(answer)) + "\n")
                file.flush()
                os.fsync(file.fileno())
            self._remember(answer)
