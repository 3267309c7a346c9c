"""An onboard unit handed to the supervisors of its binding, its handoff followed as it changes.

A console's start of a run on the habitat and ``caretaker run --onboard --via-supervisor`` hand a
unit the same way (:mod:`records.onboard_handoffs`): listening on the change feed before the
handoff is written, so that no notice of it is missed; then woken by the handoff's and the run's
notices, never polling the database on a timer: until a supervisor takes it (else it is
withdrawn, and nothing went up), then until the habitat took the unit.
"""

from __future__ import annotations

import threading
import time

from ground.change_feed import ChangeNotice, open_change_feed
from records.audit_log import AuditLog
from records.onboard_handoffs import DETACHED, ENDED, HANDED, UPLINKED, WITHDRAWN, Handoff, OnboardHandoffs

__all__ = ["HandedRun"]

#: How long to wait for the change feed's connection before handing the unit over (s).
_LISTENING_WITHIN_S = 30.0


class HandedRun:
    """Run ``run_id``'s handoff, from the moment it is handed until :meth:`close`."""

    def __init__(self, audit: AuditLog, run_id: str) -> None:
        self.run_id = run_id
        self.handoffs = OnboardHandoffs(audit.engine)
        self._audit = audit
        self._news = threading.Event()
        self._feed = open_change_feed(audit.engine)
        self._feed.subscribe(self._notice)

    def _notice(self, change: ChangeNotice) -> None:
        about = change.payload.split()[-1:] == [self.run_id]  # handoffs: "<state> <run>", events: "<seq> <kind> <run>"
        if change.channel == "resync" or (change.channel in ("handoffs", "events") and about):
            self._news.set()

    def hand(self, *, binding: str, unit_json: str, user: str, at_consoles: bool) -> None:
        """Hand the unit (unsigned: the supervisor signs it) to the supervisors of ``binding``."""
        self._feed.connected.wait(_LISTENING_WITHIN_S)  # listening first: no notice of it is missed
        self.handoffs.hand(self.run_id, binding=binding, unit_json=unit_json, user=user, at_consoles=at_consoles)

    def wait(self, timeout: float) -> None:
        """Until a notice about the run (or ``timeout``); read the database after it, not before."""
        self._news.wait(timeout)
        self._news.clear()

    def taken(self, within: float) -> Handoff | None:
        """The handoff once a supervisor took it; None if none did within ``within`` s: it is then
        withdrawn (a supervisor taking it at that moment wins, and the handoff is returned)."""
        deadline = time.monotonic() + within
        while (handoff := self._handoff()).state == HANDED:
            left = deadline - time.monotonic()
            if left <= 0:
                if self.handoffs.withdraw(self.run_id):
                    return None
                continue  # taken meanwhile
            self.wait(left)
        return handoff

    def ready(self, within: float) -> tuple[Handoff, bool]:
        """The taken handoff once the habitat took the unit (True), or once it ended or was left
        without that, or ``within`` s ran out (False)."""
        deadline = time.monotonic() + within
        while True:
            handoff = self._handoff()
            if handoff.state == UPLINKED or self.has_events():
                return handoff, True
            left = deadline - time.monotonic()
            if handoff.state in (ENDED, DETACHED, WITHDRAWN) or left <= 0:
                return handoff, False
            self.wait(left)

    def has_events(self) -> bool:
        """Whether the run has stored an event: the habitat runs it (its first answer may come
        before its supervisor marks the handoff uplinked)."""
        return bool(self._audit.events(self.run_id))

    def _handoff(self) -> Handoff:
        handoff = self.handoffs.get(self.run_id)
        assert handoff is not None  # handoffs are never removed
        return handoff

    def close(self) -> None:
        """Stop listening (the handoff stays as it is)."""
        self._feed.close()
