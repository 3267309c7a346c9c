"""A run's events in words: one line per audit record, as the audit panel, the report and the terminal say it.

Commands read as their instruction's sentence with the values sent, results as their outcome,
the system's message and its values labelled and rounded, readings as "Plan Valid = true",
all through :mod:`pride.phrasing`, so every view says the same thing the same way.
:func:`describe_event` folds over every kind of :mod:`pride.event_payloads` (a kind added there
and not worded here fails mypy).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import assert_never

from pride import event_payloads as ep
from pride.events import Event
from pride.phrasing import (
    Wording,
    command_definition,
    command_text,
    condition_words,
    fill_text,
    format_value,
    humanize,
    in_order,
    labelled_values,
    raw_call,
    telemetry_item,
    telemetry_label,
)

__all__ = ["describe_event", "reading_words", "result_text", "started_text", "telemetry_text", "version_text"]

#: How a command's outcome reads; an unknown one is neither a success nor a failure.
_OUTCOME_WORDS = {"succeeded": "succeeded", "failed": "FAILED", "unknown": "OUTCOME UNKNOWN", "halted": "HALTED"}


def _reason(reason: str) -> str:
    return f": {reason}" if reason else ""


def started_text(event: Event) -> str:
    """The sentence of an instruction-started event as people read it: with the values the run knew
    when it began filled in (``text_filled``), else, in a log recorded before events carried that,
    the author's text, its references said to be not known (the record does not hold them)."""
    data = event.data
    if not isinstance(data, ep.InstructionStarted):
        return ""
    return data.text_filled if data.text_filled is not None else fill_text(data.text, {})


def _values(data: ep.CommandResult, wording: Wording) -> str:
    if not data.values:
        return ""
    lines = labelled_values(data.values, wording.sysreps.get(data.system))
    return " · " + ", ".join(f"{label} {text}" for label, text in lines)


def _sent_text(data: ep.CommandSent, wording: Wording) -> str:
    """A COMMAND_SENT record in words: "sent" (again, when its key was re-sent), the command as its
    instruction reads, a hazard mark; with the raw switch, the call as sent after it."""
    system, command, args = data.system, data.command, data.args
    text = f"sent{' again' if data.resend else ''} {command_text(system, command, args, wording.sysreps)}"
    text += " [hazardous]" if data.hazardous else ""
    if data.approved_by:
        text += f" (sent by {data.requested_by}, approved by {data.approved_by})"
    if not wording.raw:
        return text
    ordered = dict(in_order(args, command_definition(system, command, wording.sysreps)))
    return f"{text} · raw: {raw_call(system, command, ordered)}"


def result_text(data: ep.CommandResult, wording: Wording, outcomes: Mapping[str, str] = _OUTCOME_WORDS) -> str:
    """A COMMAND_RESULT record in words: its outcome (as ``outcomes`` says it), the system's
    message and the values it returned, labelled and rounded."""
    success = "succeeded" if data.success else "failed"
    outcome = outcomes.get(data.outcome, outcomes[success])
    message = f": {data.message}" if data.message else ""
    return f"{outcome}{message}{_values(data, wording)}"


def reading_words(data: ep.TelemetrySeen, wording: Wording) -> tuple[str, str, str]:
    """A TELEMETRY_SEEN record as the procedure view words it: the item's label, the value read
    (rounded, in its units, "(stale)" when it was) and the condition it was checked against
    ("" for a branch's reading, which has none of its own)."""
    system, item = str(data.system), data.item
    found = telemetry_item(system, item, wording.sysreps)
    units = found.units if found is not None else None
    value = format_value(data.value, units, name=item) + (" (stale)" if data.stale else "")
    condition = condition_words(data.condition, units) if data.condition else ""
    return telemetry_label(system, item, wording.sysreps), value, condition


def telemetry_text(data: ep.TelemetrySeen, wording: Wording) -> str:
    """A TELEMETRY_SEEN record's reading in words: ``Plan Valid = true (stale)``."""
    label, value, _ = reading_words(data, wording)
    return f"{label} = {value}"


def version_text(data: ep.RunStarted) -> str:
    """The procedure version of a run_started record: " · release 3 (sha256 ab12cd34…)" or
    " · REHEARSAL of a draft (…)"; "" for a run recorded without one."""
    if not data.sha256:
        return ""
    which = f"release {data.release}" if data.release else "a draft, not released"
    what = f"REHEARSAL on a simulator, {which}" if data.rehearsal else which
    return f" · {what} (sha256 {data.sha256[:8]}…)"


def _clock(iso: str | None) -> str:
    """The time of day of an ISO UTC time, as a log line says it."""
    return str(iso)[11:19]


def describe_event(event: Event, wording: Wording | None = None) -> str:
    """One line saying what an audit record was, in words (the web view's log and the report)."""
    said = wording or Wording()
    match event.data:
        case ep.RunStarted() as d:
            return f"started {d.procedure} v{d.version} in {d.mode} mode{version_text(d)}"
        case ep.RunResumed() as d:
            return f"resumed in {d.mode} mode" + (" (a command was in flight)" if d.in_flight else "")
        case ep.CommandSent() as d:
            return _sent_text(d, said)
        case ep.CommandResult() as d:
            return result_text(d, said)
        case ep.TelemetrySeen() as d:
            verdict = "" if d.ok is None else (" ✓" if d.ok else " ✗")
            return f"saw {telemetry_text(d, said)}{verdict}"
        case ep.OperatorInput() as d:
            return f"recorded {humanize(d.name)} = {format_value(d.value)}"
        case ep.InstructionFailed() as d:
            return f"failed: {d.reason}" + (f" → step {d.branch}" if d.branch else "")
        case ep.InstructionSkipped() as d:
            return f"skipped: {d.reason}"
        case ep.InstructionCompleted() as d:
            return "completed" + (f" → step {d.went_to}" if d.went_to else "")
        case ep.InstructionStarted():
            return f"started: {started_text(event)}"
        case ep.AwaitingOperator() as d:
            return f"waiting for an operator: {d.reason}"
        case ep.ModeChanged() as d:
            return f"mode → {d.mode}"
        case ep.RunStopped() as d:
            return f"stopped: {d.reason}"
        case ep.Retry() as d:
            return f"retry after: {d.after}"
        case ep.CallEntered() as d:
            return f"entered {d.procedure} with {format_value(dict(d.inputs)) or 'no inputs'}"
        case ep.MonitorViolated() as d:
            then = f"HALT, then go to step {d.action.partition(':')[2]}"
            acts = {"hold": "the run holds", "halt": "HALT"}.get(d.action, then)
            return f"monitor violated: {d.system}.{d.telemetry} = {format_value(d.value)} ({d.limit}): {acts}"
        case ep.MonitorCleared() as d:
            return f"monitor cleared: {d.system}.{d.telemetry} = {format_value(d.value)}"
        case ep.WentTo() as d:
            return f"went to {d.next}{_reason(d.reason)}"
        case ep.ValueSet() as d:
            return f"set {humanize(d.name)} to {format_value(d.value)}"
        case ep.CallReturned() as d:
            return f"{d.procedure} returned {format_value(dict(d.outputs)) or 'no outputs'}"
        case ep.Confirmation() as d:
            return f"confirmed the hazardous command: {fill_text(d.command or '', {})}"
        case ep.ApprovalRequested() as d:
            return f"sent for a second operator's approval: {d.command}"
        case ep.ApprovalGiven() as d:
            carried = f", given on the ground at {_clock(d.given)} UTC and carried up" if d.carried else ""
            return f"approved {d.sender}'s command: {d.command} (good until {_clock(d.expires)} UTC{carried})"
        case ep.ApprovalExpired() as d:
            return (
                f"{d.approver}'s approval of {d.sender}'s command ran out at {_clock(d.expired)} "
                "UTC before it could be sent: nothing sent, it waits for a new approval"
            )
        case ep.ActionRefused() as d:
            return f"refused {humanize(d.action)} by the {humanize(d.rule)} rule: {d.reason}"
        case ep.SupervisorAttached() as d:
            return f"attached {d.supervisor} to supervise onboard run {d.run}"
        case ep.Halt() as d:
            told = d.cancel_message
            return f"HALT{_reason(d.reason)}" + (f"; the system: {told}" if told else "")
        case ep.InstructionHalted() as d:
            return f"halted before it finished{_reason(d.reason)}"
        case ep.OutcomeResolved() as d:
            return f"recorded the unknown outcome as {d.outcome}{_reason(d.reason)}"
        case ep.RecordCorrected() as d:
            old, new = format_value(d.old), format_value(d.value)
            return f"corrected {humanize(d.name)}: {old} → {new}{_reason(d.reason)}"
        case ep.SteppedBack() as d:
            return f"went back to {d.next}{_reason(d.reason)}"
        case ep.LinkLost() as d:
            n = d.in_flight
            what = "no news from the habitat" if d.quiet else "link lost"  # quiet: held, not yet given up
            return f"{what} since {_clock(d.since)} UTC, {n} command{'' if n == 1 else 's'} in flight"
        case ep.LinkRestored() as d:
            return f"link restored after {d.seconds} s"
        case ep.ControlTaken() as d:
            return f"took control of {d.robot} from run {d.from_run} ({d.from_user}){_reason(d.reason)}"
        case ep.ControlLost() as d:
            return f"control of {d.robot} taken over by {d.by_user} (run {d.by_run}){_reason(d.reason)}"
        case (
            ep.RunCompleted()
            | ep.Paused()
            | ep.Continued()
            | ep.BreakpointSet()
            | ep.BreakpointCleared()
            | ep.BreakpointHit()
        ):
            return event.kind.value.replace("_", " ")
        case _:
            assert_never(event.data)
