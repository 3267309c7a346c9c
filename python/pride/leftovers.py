"""What a run added to its systems and has not removed, so that a run that ends early takes it back.

A procedure adds an Affordance Template instance (``add_affordance_template``) and removes it
(``delete_affordance_template``) when it is done: the shipped procedures do in their last step. A
run that ends on the way (failed and stopped unattended, halted and stopped, stopped, abandoned at
a terminal) would leave its instances on the AT server, which keeps them: with a deployment's state
folder even across restarts, so the next run's instance would be ``cdra_filter:2``, not ``:0``.

:class:`Holdings` follows a run's events (the procedure's commands and operators' ad hoc ones)
and knows what the run added and still holds. Each :class:`Undo` says which SysRep command adds
something, which command removes it, and how the add's result names it; adding another kind of
thing a run should take back is adding an :class:`Undo`. The executive takes back what is held
when a run stops (:meth:`pride.executive.Executive.stop`) through the gateway, recorded like any
command; what it cannot or may not take back is listed in the run's end event (``left_behind``)
for the operator. A completed run takes nothing back: what its procedure left there was left on
purpose or by an operator's skip, and is listed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from pride.event_payloads import CommandResult, CommandSent, OutcomeResolved
from pride.events import Event

__all__ = ["UNDOS", "Held", "Holdings", "Leftover", "TakenBack", "Undo", "taken_back"]


@dataclass(frozen=True)
class Undo:
    """How a run takes back what one SysRep command adds."""

    system: str  # the SysRep (the procedure's ``system=``)
    adds: str  # the command that adds a thing
    removes: str  # the command that removes it
    name: str  # the result value, of the add and of the removal alike, that names the thing
    arguments: Callable[[Mapping[str, Any]], dict[str, Any]]  # the removal's arguments, from the add's values


#: What runs take back: the AT SysRep's instances (their results name them ``cdra_filter:0``).
UNDOS: tuple[Undo, ...] = (
    Undo(
        "affordance_templates",
        "add_affordance_template",
        "delete_affordance_template",
        "instance",
        # a negative id would have the plugin resolve the name; the add's id says the same, readably
        lambda values: {"affordance_template": values["instance"], "id": values.get("id", -1)},
    ),
)


@dataclass(frozen=True)
class Held:
    """A thing the run added and has not removed: its name, and how to remove it."""

    undo: Undo
    name: str
    arguments: dict[str, Any]


@dataclass(frozen=True)
class Leftover:
    """Something a run leaves on a system when it ends, and why it is still there."""

    system: str
    name: str
    why: str

    def to_json(self) -> dict[str, str]:
        return {"system": self.system, "name": self.name, "why": self.why}


@dataclass(frozen=True)
class TakenBack:
    """How a run's end dealt with what it had added: what it removed, and what it leaves behind."""

    removed: tuple[str, ...] = ()
    left: tuple[Leftover, ...] = ()

    def left_json(self) -> tuple[dict[str, str], ...]:
        """What is left behind as the end event's ``left_behind`` records it."""
        return tuple(leftover.to_json() for leftover in self.left)


class Holdings:
    """What one run added to its systems and still holds, as its events tell (see the module docstring)."""

    def __init__(self, undos: Iterable[Undo] = UNDOS) -> None:
        undos = tuple(undos)
        self._adding = {(u.system, u.adds): u for u in undos}
        self._removing = {(u.system, u.removes): u for u in undos}
        self._held: dict[tuple[str, str], Held] = {}  # (system, name), in the order they were added
        self._unsure: dict[str, Leftover] = {}  # key of an add whose outcome is not known -> what to say

    def note(self, event: Event) -> None:
        """Take one of the run's events into account (every event may be given; most change nothing)."""
        data = event.data
        if isinstance(data, OutcomeResolved):
            unsure = self._unsure.get(data.key)
            if unsure is None:
                return
            if data.outcome == "failed":
                del self._unsure[data.key]
            else:  # the operator saw it succeed; the system's answer, which names the thing, never came
                why = f"recorded as succeeded by {event.actor}, so its name is not known: check the system"
                self._unsure[data.key] = Leftover(unsure.system, unsure.name, why)
            return
        if not isinstance(data, CommandResult):  # only results and resolutions change what is held
            return
        system, command, key, values = data.system, data.command, str(data.key), data.values
        adding, removing = self._adding.get((system, command)), self._removing.get((system, command))
        if adding is not None:
            self._unsure.pop(key, None)  # asked again under the same key: this is its answer
            name = values.get(adding.name)
            if data.success is True and name is not None:
                self._held[(system, str(name))] = Held(adding, str(name), adding.arguments(values))
            elif data.success is True or data.outcome == "unknown":
                args = ", ".join(f"{k}={v!r}" for k, v in data.args.items())
                why = "its answer named nothing" if data.success else f"the outcome of {key} is not known"
                self._unsure[key] = Leftover(system, f"{command}({args})", f"{why}: it may have added something")
        elif removing is not None and data.success is True:
            self._held.pop((system, str(values.get(removing.name))), None)

    def held(self) -> list[Held]:
        """What the run added and has not removed, oldest first."""
        return list(self._held.values())

    def unsure(self) -> list[Leftover]:
        """Adds whose outcome is not known: there may be something the run cannot name."""
        return list(self._unsure.values())

    def left(self, why: str) -> TakenBack:
        """Everything held, left behind for ``why``, with the adds of unknown outcome."""
        held = tuple(Leftover(h.undo.system, h.name, why) for h in self._held.values())
        return TakenBack(left=held + tuple(self._unsure.values()))


def taken_back(events: Iterable[Event]) -> list[str]:
    """What a run's events show it sent to take back (it stopped for good): names, in order."""
    return [e.data.take_back for e in events if isinstance(e.data, CommandSent) and e.data.take_back]
