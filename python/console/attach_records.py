"""Attaches on the record: who attached a supervising runner to an onboard run and when, and who was refused.

The ground's log of an onboard run is the habitat's chain, kept hash for hash, so nothing of the
ground's may be added to it. An attach is recorded as a refused start is
(:mod:`console.start_refusals`): under a run id of its own, ``<run>-attach-<UTC>-<hex>``, as that
id's only event, with the operator as its actor: ``supervisor_attached`` by the runner that took
the run over (``caretaker run --attach``, at a terminal or started by a console), or
``action_refused`` (``attach``) by whichever refused it, the console or the runner.
"""

from __future__ import annotations

from pride import event_payloads as ep
from pride.events import Event
from pride.run_setup import new_run_id
from pride.states import RefusalRule
from records.audit_log import AuditLog

__all__ = ["record_attach_refused", "record_attached"]


def record_attached(audit_log: AuditLog, user: str, run_id: str, supervisor: str) -> str:
    """Record that ``user`` attached ``supervisor`` (the runner, as consoles name it) to ``run_id``; the record's id."""
    return _record(audit_log, user, run_id, ep.SupervisorAttached(run=run_id, supervisor=supervisor))


def record_attach_refused(audit_log: AuditLog, user: str, run_id: str, rule: RefusalRule, reason: str) -> str:
    """Record that ``rule`` refused ``user``'s attach to ``run_id``, with the words they read; the record's id."""
    refused = ep.ActionRefused(action="attach", rule=rule.value, reason=reason, asked={"run": run_id})
    return _record(audit_log, user, run_id, refused)


def _record(audit_log: AuditLog, user: str, run_id: str, payload: ep.Payload) -> str:
    own = new_run_id(f"{run_id}-attach")
    audit_log.append(Event.of(own, 1, user, None, payload))
    return own
