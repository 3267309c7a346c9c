"""Commands a run sends outside its procedure's instructions: an operator's, and a stop's take-back.

An operator may send a command the procedure does not hold (a registration dragged in the 3D
view: :meth:`pride.executive.Executive.operator_command`), and a stop removes what the run added
to its systems (:meth:`pride.executive.Executive.stop`, :mod:`pride.leftovers`). Both go through
the run's gateway and journal like any command: COMMAND_SENT and COMMAND_RESULT without an
instruction number, marked ``ad_hoc``, each under a key of its own (``<run>/<kind>/<seq>``) that
the habitat executes at most once. The run's position does not change; an unknown outcome stays
unknown.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from pride.event_payloads import CommandResult as CommandResultRecord
from pride.event_payloads import CommandSent
from pride.leftovers import Leftover, TakenBack
from pride.run_engine import RunEngine
from pride.systems import CommandResult, Outcome

__all__ = ["record_sent", "send_recorded", "take_back"]

log = logging.getLogger(__name__)


def record_sent(
    engine: RunEngine,
    user: str,
    kind: str,
    system: str,
    command: str,
    args: Mapping[str, Any],
    take_back: str | None = None,
) -> CommandSent:
    """Record, as ``user``, COMMAND_SENT of a command that is no instruction (the lock is held) and
    return it; ``kind`` names its key's middle part (``operator``, ``take-back``)."""
    key = f"{engine.run_id}/{kind}/{engine.seq + 1}"
    sent = CommandSent(
        system=system, command=command, args=dict(args), key=key, hazardous=False, ad_hoc=True, take_back=take_back
    )
    engine.emit(user, None, sent)
    return sent


def send_recorded(engine: RunEngine, user: str, sent: CommandSent) -> CommandResult:
    """Send the command :func:`record_sent` recorded and record its answer (unknown stays unknown)."""
    try:
        result = engine.gateway.execute(sent.system, sent.command, dict(sent.args), key=sent.key)
    except Exception as exc:  # refused before sending (bad argument, unknown command)
        result = CommandResult(Outcome.FAILED, f"not sent: {type(exc).__name__}: {exc}")
    outcome = result.outcome
    answer = CommandResultRecord(
        system=sent.system,
        command=sent.command,
        args=sent.args,
        key=sent.key,
        outcome=outcome.value,
        success=None if outcome is Outcome.UNKNOWN else result.success,
        message=result.message,
        values=dict(result.values),
        ad_hoc=True,
        take_back=sent.take_back,
    )
    engine.record(user, None, answer)
    return result


def take_back(engine: RunEngine, user: str) -> TakenBack:
    """Remove, as ``user``, what the run added and still holds (the lock is held, PAX's thread idle).

    A removal that fails, or whose outcome is not known, is listed as left behind with the
    system's words; where removing could not be honest nothing is sent (:func:`_why_not`).
    """
    why_not = _why_not(engine)
    if why_not is not None:
        return engine.holdings.left(f"not removed: {why_not}")
    removed: list[str] = []
    left = engine.holdings.unsure()
    for held in engine.holdings.held():
        undo = held.undo
        sent = record_sent(engine, user, "take-back", undo.system, undo.removes, held.arguments, take_back=held.name)
        result = send_recorded(engine, user, sent)
        if result.success:
            removed.append(held.name)
        else:
            log.warning("run %s left %s on %s: %s", engine.run_id, held.name, undo.system, result.message)
            left.append(Leftover(undo.system, held.name, f"{undo.removes} {result.outcome.value}: {result.message}"))
    return TakenBack(tuple(removed), tuple(left))


def _why_not(engine: RunEngine) -> str | None:
    """Why the run must not send removals now, or None: its link is lost (their answers would not
    be known), a command's outcome is not known (a resume asks about it, and needs what the run
    added), or another run controls the robot."""
    if engine.links.now().lost_since is not None:
        return f"the link to robot {engine.robot} is lost"
    pending = engine.pending_key()
    if pending is not None:
        return f"the outcome of {pending} is not known"
    if engine.state.in_flight:  # a log from before command keys
        return f"the outcome of the command of {engine.state.current_number()} is not known"
    lost, holder = engine.control.lost()
    return engine.control.lost_text(holder) if lost else None
