"""The agent's proposal an operator accepted to start a run, as the run's record names it.

An assistant agent may only propose a run; an operator accepts it and the run starts under the
operator's name. Its ``run_started`` then carries this (``proposal``), so the record says both who
started the run and which agent's proposal, for what reason, it answered.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["AcceptedProposal"]


@dataclass(frozen=True)
class AcceptedProposal:
    """Proposal ``id`` of ``agent``, made for ``reason``."""

    id: int
    agent: str
    reason: str

    def to_json(self) -> dict[str, Any]:
        return {"id": self.id, "agent": self.agent, "reason": self.reason}

    @classmethod
    def from_json(cls, data: Any) -> AcceptedProposal:
        """Read one back (a unit's ``proposal``); ValueError says what is wrong with it."""
        if not isinstance(data, Mapping) or set(data) != {"id", "agent", "reason"}:
            raise ValueError('proposal must be an object of "id", "agent" and "reason"')
        if type(data["id"]) is not int or not all(isinstance(data[k], str) for k in ("agent", "reason")):
            raise ValueError("proposal.id must be an integer, proposal.agent and proposal.reason text")
        return cls(data["id"], data["agent"], data["reason"])
