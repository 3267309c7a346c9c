"""What every agent did, in the audit log's way: each call, its arguments and its answer or refusal.

One chain per agent in ``agent_records`` (:mod:`records.agent_tables`), hashed exactly as a run's
audit records are (:func:`records.audit_chain.link_hash`, the agent's id in place of the run id,
the tool in place of the instruction), so :func:`records.audit_chain.verify_chain` checks it and
names the first record changed, removed or rewritten. The table is append-only (triggers of
revision 0007). Two servers of one agent may append at once: the one that finds its number taken
reads the new head and links after it.
"""

from __future__ import annotations

import json
import threading
from dataclasses import replace
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import insert, select
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import IntegrityError

from records.agent_tables import agent_records
from records.audit_chain import GENESIS, ChainCheck, StoredEvent, utc, verify_chain

__all__ = ["ANSWERED", "REFUSED", "AgentRecords", "record_line"]

#: A call answered, and a call refused (its data names the rule).
ANSWERED = "answered"
REFUSED = "refused"
_R = agent_records.c
_ATTEMPTS = 20


class AgentRecords:
    """The ``agent_records`` chains of one ground database. Thread-safe (one connection per call)."""

    def __init__(self, engine: Engine) -> None:
        self._engine = engine
        # This process's writers one at a time: a burst of refusals (bad bearer tokens arrive on
        # many threads) would only contend for the chain's head, and SQLite would give up on it.
        self._appending = threading.Lock()

    def append(self, agent: str, kind: str, tool: str, data: dict[str, Any]) -> StoredEvent:
        """Store one record at the head of ``agent``'s chain and commit it."""
        with self._appending:
            return self._append(agent, kind, tool, data)

    def _append(self, agent: str, kind: str, tool: str, data: dict[str, Any]) -> StoredEvent:
        text = json.dumps(data, sort_keys=True, default=str, ensure_ascii=False)
        for _ in range(_ATTEMPTS):
            try:
                # the head is read, then written after: on SQLite the write lock is taken first (BEGIN
                # IMMEDIATE waits for it), or a writer that commits between the two fails this one at once
                immediate = self._engine.connect().execution_options(sqlite_begin="BEGIN IMMEDIATE")
                with immediate as connection, connection.begin():
                    seq, prev = _head(connection, agent)
                    unlinked = StoredEvent(agent, seq + 1, datetime.now(UTC), agent, kind, tool, text, prev)
                    row = replace(unlinked, hash=unlinked.expected_hash())
                    connection.execute(
                        insert(agent_records).values(
                            agent=agent,
                            seq=row.seq,
                            time=row.time,
                            kind=kind,
                            tool=tool,
                            data=text,
                            prev_hash=prev,
                            hash=row.hash,
                        )
                    )
            except IntegrityError:  # another server of this agent took the number: link after it
                continue
            return row
        raise RuntimeError(f"agent {agent}: could not append a record in {_ATTEMPTS} attempts (too many writers)")

    def records(self, agent: str) -> list[StoredEvent]:
        """``agent``'s records in order."""
        query = select(_R.agent, _R.seq, _R.time, _R.agent, _R.kind, _R.tool, _R.data, _R.prev_hash, _R.hash).where(
            _R.agent == agent
        )
        with self._engine.connect() as connection:
            rows = connection.execute(query.order_by(_R.seq)).all()
        return [StoredEvent(row[0], row[1], utc(row[2]), *row[3:]) for row in rows]

    def verify(self, agent: str) -> ChainCheck:
        """Check ``agent``'s chain as stored."""
        return verify_chain(agent, self.records(agent))


def _head(connection: Connection, agent: str) -> tuple[int, str]:
    last = connection.execute(select(_R.seq, _R.hash).where(_R.agent == agent).order_by(_R.seq.desc()).limit(1)).first()
    return (0, GENESIS) if last is None else (int(last.seq), str(last.hash))


def record_line(record: StoredEvent) -> str:
    """One agent record as ``caretaker report --agent`` lists it.

    What the agent sent and what it was told are printed as JSON, never as raw text: an agent's
    strings (and the habitat's, quoted in answers) cannot move a terminal's cursor or fake a line.
    """
    data = json.loads(record.data)
    said = json.dumps(data.get("arguments", {}), sort_keys=True, ensure_ascii=False)
    if record.kind == REFUSED:
        told = f"refused by rule {data.get('rule')}: {json.dumps(data.get('refusal'), ensure_ascii=False)}"
    else:
        told = "answered " + json.dumps(data.get("answer", data), sort_keys=True, ensure_ascii=False)
    return f"{record.seq:>5}  {record.time:%Y-%m-%d %H:%M:%S}Z  {record.instruction}  {said}  {told}"
