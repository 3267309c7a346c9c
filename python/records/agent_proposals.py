"""Runs an agent proposes: a released version, a robot, inputs and the agent's reason, until an operator answers.

A proposal is a row of ``agent_proposals`` (:mod:`records.agent_tables`), ``open`` until its
agent withdraws it, an operator accepts (the run starts under the operator's name) or declines it
with a reason, or it expires (:data:`DEFAULT_EXPIRY`, by default 15 minutes after it was made).
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

__all__ = ["DEFAULT_EXPIRY", "NewProposal", "Proposal", "ProposalStore"]

#: How long a proposal waits for an operator.
DEFAULT_EXPIRY = timedelta(minutes=15)
OPEN = "open"
_P = agent_proposals.c


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

    def proposals(self, *, agent: str | None = None, open_only: bool = False) -> list[Proposal]:
        """Proposals, newest first (of ``agent``; only those still open)."""
        query = select(agent_proposals).order_by(_P.id.desc())
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
    )
    closed = utc(row.closed) if row.closed is not None else None
    return Proposal(int(row.id), proposed, utc(row.created), expires, state, closed, row.closed_by, row.answer)
