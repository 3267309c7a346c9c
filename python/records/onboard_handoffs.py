"""Onboard runs handed to a supervising ground process (``caretaker supervise``) through the ground database.

``caretaker run --onboard --via-supervisor`` builds and checks its unit as ever, and instead of
opening a session to the habitat itself hands the unit over here; a supervisor serving the
unit's binding takes it, uplinks it on the session it keeps open and follows the run to its end,
keeping the run's record in the audit log of the same database, where the runner follows it.

A handoff's ``state`` goes ``handed`` → ``taken`` (by one supervisor) → ``uplinked`` (the habitat
accepted the unit) → ``ended`` (``result``: the run's status, or why the habitat did not take
it); ``withdrawn`` when its runner stopped waiting before any supervisor took it; ``detached``
when its supervisor stopped and the run goes on on the habitat (``caretaker run --attach`` catches
its record up and follows it, or another supervisor of the binding takes it over). Each step is
one conditional UPDATE from the state (and supervisor) before it, so a run is taken by one
supervisor only, a runner withdrawing it races a supervisor taking it safely, and of the
supervisors that find a run whose supervisor is gone, one takes it over. The supervisor that
took a run also holds it as any host holds a live run, under a lease it renews (``run_hosts``,
:mod:`ground.run_hosts`): what lets a later supervisor tell a run whose supervisor died from one
that is being supervised.

PostgreSQL: a trigger NOTIFYs ``caretaker_handoffs`` with ``<state> <run id>`` at every row added
and every change of state (revision 0006 of :mod:`records.migrations`); on SQLite the change feed
reads the table (:mod:`ground.change_feed`). The runner role may read, add and update rows.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import Boolean, Column, DateTime, MetaData, String, Table, Text, insert, select, update
from sqlalchemy.engine import Engine

__all__ = ["DETACHED", "HANDED", "SUPERVISOR_WITHIN_S", "TAKEN", "Handoff", "OnboardHandoffs", "onboard_handoffs"]

_metadata = MetaData()
_WHEN = DateTime(timezone=True)

#: The states of a handoff, in order (withdrawn and detached beside them).
HANDED, TAKEN, UPLINKED, ENDED, WITHDRAWN, DETACHED = "handed", "taken", "uplinked", "ended", "withdrawn", "detached"

#: How long a runner waits for a supervisor to take its run, by default (s): a supervisor hears of a
#: handed run at once (PostgreSQL) or within a quarter second (SQLite), even on a busy machine.
SUPERVISOR_WITHIN_S = 30.0

#: The table, as revision 0006 creates it.
onboard_handoffs = Table(
    "onboard_handoffs",
    _metadata,
    Column("run_id", String(120), primary_key=True),
    Column("binding", String(200), nullable=False, index=True),  # the unit's binding (file name)
    Column("unit_json", Text, nullable=False),  # unsigned: the supervisor signs it with the link's secret
    Column("handed_by", String(120), nullable=False),
    Column("handed_at", _WHEN, nullable=False),
    Column("at_consoles", Boolean, nullable=False),  # a hold waits for an operator at a console
    Column("state", String(16), nullable=False),
    Column("supervisor", String(200), nullable=True),  # as the consoles name it
    Column("taken_at", _WHEN, nullable=True),
    Column("result", String(16), nullable=True),
    Column("message", Text, nullable=True),
    Column("ended_at", _WHEN, nullable=True),
)
_T = onboard_handoffs.c


@dataclass(frozen=True)
class Handoff:
    """One handed run as the database has it."""

    run_id: str
    binding: str
    unit_json: str
    handed_by: str
    handed_at: datetime
    at_consoles: bool
    state: str
    supervisor: str | None
    result: str | None
    message: str | None
    taken_at: datetime | None = None


class OnboardHandoffs:
    """The ``onboard_handoffs`` table of the ground database behind ``engine`` (an AuditLog's)."""

    def __init__(self, engine: Engine) -> None:
        self._engine = engine

    def hand(self, run_id: str, *, binding: str, unit_json: str, user: str, at_consoles: bool) -> None:
        """Hand ``run_id``'s unit to whichever supervisor of ``binding`` takes it first."""
        with self._engine.begin() as connection:
            connection.execute(
                insert(onboard_handoffs).values(
                    run_id=run_id,
                    binding=binding,
                    unit_json=unit_json,
                    handed_by=user,
                    handed_at=datetime.now(UTC),
                    at_consoles=at_consoles,
                    state=HANDED,
                )
            )

    def get(self, run_id: str) -> Handoff | None:
        with self._engine.connect() as connection:
            row = connection.execute(select(*_COLUMNS).where(_T.run_id == run_id)).first()
        return Handoff(**row._asdict()) if row is not None else None

    def waiting(self, binding: str) -> list[Handoff]:
        """The runs handed to ``binding``'s supervisors that none has taken yet, oldest first."""
        with self._engine.connect() as connection:
            rows = connection.execute(
                select(*_COLUMNS).where(_T.binding == binding, _T.state == HANDED).order_by(_T.handed_at, _T.run_id)
            ).all()
        return [Handoff(**row._asdict()) for row in rows]

    def supervised(self, binding: str) -> list[Handoff]:
        """The runs of ``binding`` a supervisor took and whose supervision has not ended (detached
        ones too: they go on on the habitat), oldest first."""
        with self._engine.connect() as connection:
            rows = connection.execute(
                select(*_COLUMNS)
                .where(_T.binding == binding, _T.state.in_([TAKEN, UPLINKED, DETACHED]))
                .order_by(_T.handed_at, _T.run_id)
            ).all()
        return [Handoff(**row._asdict()) for row in rows]

    def take_over(self, handoff: Handoff, supervisor: str) -> bool:
        """Whether ``supervisor`` took over the run ``handoff`` says another supervisor had (as it
        says: the same state and supervisor still); a detached run is uplinked (it runs on)."""
        state = TAKEN if handoff.state == TAKEN else UPLINKED
        with self._engine.begin() as connection:
            done = connection.execute(
                update(onboard_handoffs)
                .where(_T.run_id == handoff.run_id, _T.state == handoff.state, _T.supervisor == handoff.supervisor)
                .values(
                    state=state,
                    supervisor=supervisor,
                    taken_at=datetime.now(UTC),
                    result=None,
                    message=None,
                    ended_at=None,
                )
            ).rowcount
        return bool(done)

    def take(self, run_id: str, supervisor: str) -> bool:
        """Whether ``supervisor`` took the handed run: one supervisor does."""
        return self._step(run_id, HANDED, TAKEN, supervisor=supervisor, taken_at=datetime.now(UTC))

    def uplinked(self, run_id: str) -> bool:
        """The habitat accepted the run's unit."""
        return self._step(run_id, TAKEN, UPLINKED)

    def withdraw(self, run_id: str) -> bool:
        """Whether the run was withdrawn before any supervisor took it (False: one took it first)."""
        return self._step(run_id, HANDED, WITHDRAWN, ended_at=datetime.now(UTC))

    def end(self, run_id: str, *, detached: bool, result: str, message: str = "", supervisor: str | None) -> bool:
        """``supervisor``'s supervision of the run is over (None: whoever's): it ended (``result``:
        its status), or (``detached``) its supervisor stopped while it goes on on the habitat."""
        state = DETACHED if detached else ENDED
        ended_at = datetime.now(UTC)
        condition = [_T.run_id == run_id, _T.state.in_([TAKEN, UPLINKED])]
        if supervisor is not None:  # not a supervisor's that took it over meanwhile
            condition.append(_T.supervisor == supervisor)
        with self._engine.begin() as connection:
            done = connection.execute(
                update(onboard_handoffs)
                .where(*condition)
                .values(state=state, result=result, message=message, ended_at=ended_at)
            ).rowcount
        return bool(done)

    def _step(self, run_id: str, before: str, after: str, **values: object) -> bool:
        with self._engine.begin() as connection:
            done = connection.execute(
                update(onboard_handoffs).where(_T.run_id == run_id, _T.state == before).values(state=after, **values)
            ).rowcount
        return bool(done)


_COLUMNS = (
    _T.run_id,
    _T.binding,
    _T.unit_json,
    _T.handed_by,
    _T.handed_at,
    _T.at_consoles,
    _T.state,
    _T.supervisor,
    _T.result,
    _T.message,
    _T.taken_at,
)
