"""The tables of assistant agents in the ground database, defined once (revisions 0007 and 0008
of :mod:`records.migrations`).

An agent is an account of role ``agent`` (:mod:`console.accounts`) that reaches the ground through
``caretaker agent`` (:mod:`agent.mcp_server`), never through the console's sign-in:

- ``agent_tokens``: the tokens an agent authenticates with. Only a token's SHA-256 is stored
  (a token is 32 random bytes, so a fast hash is enough: nobody can guess one to match); each
  may expire and may be revoked. ``caretaker accounts token`` (the owner) writes it, agents read it.
- ``agent_proposals``: the runs agents propose, for an operator to accept or decline, each with
  its expiry (:mod:`records.agent_proposals`; consoles answer them, agents make them).
- ``agent_records``: every call an agent made and its answer or refusal, hash-chained per agent
  exactly as a run's audit records are (:mod:`records.audit_chain`, the agent's id in place of a
  run id) and append-only like them (:mod:`agent.agent_audit`).
"""

from __future__ import annotations

from sqlalchemy import Column, DateTime, Index, Integer, MetaData, String, Table, Text, UniqueConstraint

__all__ = ["agent_proposals", "agent_records", "agent_tokens", "metadata"]

metadata = MetaData()
_WHEN = DateTime(timezone=True)

#: An agent's tokens: their hashes, when they stop being valid, and whether they were revoked.
agent_tokens = Table(
    "agent_tokens",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("user_id", String(64), nullable=False, index=True),
    Column("token_sha256", String(64), nullable=False, unique=True),
    Column("created", _WHEN, nullable=False),
    Column("expires", _WHEN, nullable=True),  # None: until revoked
    Column("revoked", _WHEN, nullable=True),
)

#: A run an agent proposes, and what became of it (open, withdrawn, accepted, declined; expired by time).
agent_proposals = Table(
    "agent_proposals",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("agent", String(64), nullable=False),
    Column("procedure", String(120), nullable=False),  # the procedure's id
    Column("procedure_file", String(200), nullable=False),  # its file in the consoles' procedures folder
    Column("sha256", String(64), nullable=False),
    Column("release", Integer, nullable=False),
    Column("robot", String(120), nullable=False),
    Column("binding", String(200), nullable=False),
    Column("inputs", Text, nullable=False),  # JSON object
    Column("reason", Text, nullable=False),
    Column("created", _WHEN, nullable=False),
    Column("expires", _WHEN, nullable=False),
    Column("state", String(16), nullable=False),
    Column("closed", _WHEN, nullable=True),
    Column("closed_by", String(64), nullable=True),
    Column("answer", Text, nullable=True),  # an operator's reason for declining
    Column("cited", Text, nullable=True),  # JSON list: the telemetry the agent cited, as read then (revision 0008)
    Column("run_id", String(120), nullable=True),  # the run an accepted proposal started (revision 0008)
    Index("ix_agent_proposals_state", "state"),
)

#: Every call of every agent, hash-chained per agent: the columns of ``audit_records``, the agent's
#: id as the chain's id, the tool as its instruction.
agent_records = Table(
    "agent_records",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("agent", String(64), nullable=False),
    Column("seq", Integer, nullable=False),
    Column("time", _WHEN, nullable=False),
    Column("kind", String(40), nullable=False),  # answered | refused
    Column("tool", String(80), nullable=False),
    Column("data", Text, nullable=False),
    Column("prev_hash", String(64), nullable=False),
    Column("hash", String(64), nullable=False),
    UniqueConstraint("agent", "seq", name="one_agent_record_per_seq"),
)
