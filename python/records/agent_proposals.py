"""Runs an agent proposes: a released version, a robot, inputs and the agent's reason, until an operator answers.

A proposal is a row of ``agent_proposals`` (:mod:`records.agent_tables`), ``open`` until its
agent withdraws it, an operator accepts (the run starts under the operator's name, and the row
keeps its id) or declines it with a reason, or it expires (:data:`DEFAULT_EXPIRY`, by default 15
minutes after it was made). An acceptance whose run could not start opens the proposal again
with the reason, so nothing an agent proposed is lost to a failed start.
Expiry is read from the clock, not written: an open row past its expiry *is* expired, so no
process has to be alive to expire it. Every change is one UPDATE conditioned on the row still
being open, so a withdrawal and an acceptance at once cannot both win.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import insert, select, update
from sqlalchemy.engine import Engine

from records.agent_tables import agent_proposals
from records.audit_chain import utc

__all__ = ["DEFAULT_EXPIRY", "CitedTelemetry", "NewProposal", "Proposal", "ProposalStore"]

#: How long a proposal waits for an operator.
DEFAULT_EXPIRY = timedelta(minutes=15)
OPEN = "open"
_P = agent_proposals.c


@dataclass(frozen=True)
class CitedTelemetry:
    """A telemetry item an agent cites for its proposal, as it read then: the value (None: not
    heard yet) and its limit state (green, yellow, red, no limits, no value, stale)."""

    system: str
    item: str
    value: Any
    state: str

    def to_json(self) -> dict[str, Any]:
        return {"system": self.system, "item": self.item, "value": self.value, "state": self.state}


@dataclass(frozen=True)
class NewProposal:
    """What an agent proposes, already checked by its desk (:mod:`agent.agent_desk`)."""

    agent: str
    procedure: str
    procedure_file: str
    sha256: str
    release: int
    robot: str
    binding: str
    inputs: dict[str, Any]
    reason: str
    cited: tuple[CitedTelemetry, ...] = ()


@dataclass(frozen=True)
class Proposal:
    """A stored proposal; ``state`` is as of when it was read (an open one past its expiry: ``expired``)."""

    id: int
    proposed: NewProposal
    created: datetime
    expires: datetime
    state: str
    closed: datetime | None
    closed_by: str | None
    answer: str | None
    run_id: str | None = None


class ProposalStore:
    """The ``agent_proposals`` of one ground database."""

    def __init__(self, engine: Engine, *, expiry: timedelta = DEFAULT_EXPIRY) -> None:
        self._engine = engine
        self.expiry = expiry

    def propose(self, new: NewProposal) -> Proposal:
        now = datetime.now(UTC)
        with self._engine.begin() as connection:
            proposal_id = connection.execute(
                insert(agent_proposals)
                .values(
                    agent=new.agent,
                    procedure=new.procedure,
                    procedure_file=new.procedure_file,
                    sha256=new.sha256,
                    release=new.release,
                    robot=new.robot,
                    binding=new.binding,
                    inputs=json.dumps(new.inputs, sort_keys=True),
                    reason=new.reason,
                    cited=json.dumps([c.to_json() for c in new.cited]),
                    created=now,
                    expires=now + self.expiry,
                    state=OPEN,
                )
                .returning(_P.id)
            ).scalar_one()
        found = self.get(int(proposal_id))
        assert found is not None
        return found

    def get(self, proposal_id: int) -> Proposal | None:
        with self._engine.connect() as connection:
            row = connection.execute(select(agent_proposals).where(_P.id == proposal_id)).first()
        return None if row is None else _proposal(row)

    def proposals(
        self, *, agent: str | None = None, open_only: bool = False, limit: int | None = None
    ) -> list[Proposal]:
        """Proposals, newest first (of ``agent``; only those still open; the ``limit`` newest)."""
        query = select(agent_proposals).order_by(_P.id.desc()).limit(limit)
        if agent is not None:
            query = query.where(_P.agent == agent)
        if open_only:
            query = query.where(_P.state == OPEN, _P.expires > datetime.now(UTC))
        with self._engine.connect() as connection:
            return [_proposal(row) for row in connection.execute(query)]

    def close(self, proposal_id: int, state: str, by: str, answer: str | None = None) -> bool:
        """Close an open, unexpired proposal as ``state`` (withdrawn, accepted, declined) by ``by``;
        False when it was not open any more (answered, withdrawn or expired meanwhile)."""
        now = datetime.now(UTC)
        with self._engine.begin() as connection:
            changed = connection.execute(
                update(agent_proposals)
                .where(_P.id == proposal_id, _P.state == OPEN, _P.expires > now)
                .values(state=state, closed=now, closed_by=by, answer=answer)
            ).rowcount
        return bool(changed)

    def started(self, proposal_id: int, by: str, run_id: str) -> bool:
        """Note ``run_id`` as the run ``by``'s acceptance of ``proposal_id`` starts; False when
        the proposal is not ``by``'s accepted one or names a run already (one acceptance, one run)."""
        with self._engine.begin() as connection:
            changed = connection.execute(
                update(agent_proposals)
                .where(_P.id == proposal_id, _P.state == "accepted", _P.closed_by == by, _P.run_id.is_(None))
                .values(run_id=run_id)
            ).rowcount
        return bool(changed)

    def reopen(self, proposal_id: int, by: str, why: str) -> None:
        """Open again a proposal ``by`` accepted whose run did not start (``why``, for the agent and
        the next operator); its expiry stands."""
        with self._engine.begin() as connection:
            connection.execute(
                update(agent_proposals)
                .where(_P.id == proposal_id, _P.state == "accepted", _P.closed_by == by)
                .values(state=OPEN, closed=None, closed_by=None, run_id=None, answer=f"not started by {by}: {why}")
            )


def _cited(text: str | None) -> tuple[CitedTelemetry, ...]:
    items = json.loads(text) if text else []
    return tuple(CitedTelemetry(str(c["system"]), str(c["item"]), c["value"], str(c["state"])) for c in items)


def _proposal(row: Any) -> Proposal:
    expires = utc(row.expires)
    state = "expired" if row.state == OPEN and expires <= datetime.now(UTC) else str(row.state)
    proposed = NewProposal(
        row.agent,
        row.procedure,
        row.procedure_file,
        row.sha256,
        int(row.release),
        row.robot,
        row.binding,
        json.loads(row.inputs),
        row.reason,
        _cited(row.cited),
    )
    closed = utc(row.closed) if row.closed is not None else None
    return Proposal(
        int(row.id), proposed, utc(row.created), expires, state, closed, row.closed_by, row.answer, row.run_id
    )
