"""A start refused by a rule is on the record, as every other refused act is.

A refused start has no run to record it in: the run never started, and nothing may be added to
another run's log. So it is recorded under a run id of its own (``<procedure>-refused-<UTC>-<hex>``)
as that id's only event, an ``action_refused`` naming the rule, the operator as its actor, and
what was asked (binding, mode, rehearsal, a takeover's reason). The runs list shows only runs
that started, so it does not list them; the audit log keeps them with every other record.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from console.actions import ActionRefused
from pride import event_payloads as ep
from pride.events import Event
from pride.run_setup import new_run_id
from records.audit_log import AuditLog

__all__ = ["recorded_start_refusals"]


@contextlib.contextmanager
def recorded_start_refusals(
    audit_log: AuditLog, user: str, procedure_name: str, asked: Mapping[str, Any]
) -> Iterator[None]:
    """Record a start refused in the block by a rule (an ActionRefused with a ``rule``), then let
    the refusal go on to the operator; a start refused for anything else (a malformed request, a
    robot side that cannot be reached) is no refused act and is not recorded."""
    try:
        yield
    except ActionRefused as exc:
        if exc.rule is not None:
            refused = ep.ActionRefused(
                action="start",
                rule=exc.rule.value,
                reason=exc.message,
                asked={"procedure": procedure_name, **{k: v for k, v in asked.items() if v not in (None, "", False)}},
            )
            run_id = new_run_id(f"{Path(procedure_name).stem}-refused")
            audit_log.append(Event.of(run_id, 1, user, None, refused))
        raise
