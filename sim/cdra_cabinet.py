"""The CDRA filter cabinet: one slot, a lock, and the telemetry a crew panel would show.

The lock is what physically holds the installed filter (see ``filter_slots.SlotBlocked``); the
lamp next to the slot turns red when locked and green when unlocked so camera images show it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import pybullet as p

from sim.filter_slots import FilterSlots
from sim.scene import CabinetSpec
from sim.world import World

__all__ = ["CdraCabinet", "CdraTelemetry", "FilterFound", "find_filter"]

LOG = logging.getLogger(__name__)

LOCKED_COLOR = (0.85, 0.1, 0.1, 1.0)
UNLOCKED_COLOR = (0.1, 0.8, 0.2, 1.0)


@dataclass(frozen=True)
class CdraTelemetry:
    filter_locked: bool
    filter_present: bool
    installed_filter_id: str
    installed_filter_condition: str
    clean_filter_ids: str  # the clean filters seated outside the cabinet (on the rack), comma-separated


@dataclass(frozen=True)
class FilterFound:
    """The bay's answer to "which filter is in this slot" or "where is this filter"."""

    found: bool
    message: str
    filter_id: str = ""
    slot: str = ""
    condition: str = ""


def find_filter(filters: FilterSlots, *, filter_id: str = "", slot: str = "") -> FilterFound:
    """The filter seated in ``slot``, or the slot ``filter_id`` is seated in (name exactly one).

    What the bay's slot sensors and the filters' tags report, so a procedure can look at the
    filter it means (the markers perception finds are that filter's), not at where the drawings
    put one. A filter in the gripper or loose is in no slot: not found, with that said.
    """
    if bool(filter_id) == bool(slot):
        return FilterFound(False, "name either a filter id or a slot, not both and not neither")
    if slot:
        if slot not in filters.slot_poses:
            return FilterFound(False, f"no slot {slot!r}; the bay has {', '.join(sorted(filters.slot_poses))}")
        seated = filters.in_slot(slot)
        if seated is None:
            return FilterFound(False, f"{slot} is empty", slot=slot)
    else:
        seated = filters.filters.get(filter_id)
        if seated is None:
            return FilterFound(False, f"no filter {filter_id!r}; the bay has {', '.join(sorted(filters.filters))}")
        if seated.slot is None:
            where = "held by the gripper" if seated.held else "not seated in any slot"
            return FilterFound(False, f"{filter_id} is {where}", filter_id=filter_id, condition=seated.condition)
    assert seated.slot is not None
    return FilterFound(
        True, f"{seated.id} ({seated.condition}) is seated in {seated.slot}", seated.id, seated.slot, seated.condition
    )


class CdraCabinet:
    """Lock state of the cabinet slot; all calls under the simulation's world lock."""

    def __init__(self, spec: CabinetSpec, world: World) -> None:
        self.slot = spec.slot
        self.locked = spec.locked
        self._world = world
        self._show_lock()

    def is_locked(self, slot: str) -> bool:
        return slot == self.slot and self.locked

    def set_locked(self, locked: bool, filters: FilterSlots) -> str:
        """Engage or release the lock; returns what happened, for the service response."""
        was = self.locked
        self.locked = locked
        self._show_lock()
        installed = filters.in_slot(self.slot)
        what = f"filter {installed.id}" if installed else "no filter installed"
        verb = "locked" if locked else "unlocked"
        LOG.info("cabinet %s (%s)", verb, what)
        return f"{self.slot} {'already ' if was == locked else ''}{verb} ({what})"

    def telemetry(self, filters: FilterSlots) -> CdraTelemetry:
        installed = filters.in_slot(self.slot)
        return CdraTelemetry(
            filter_locked=self.locked,
            filter_present=installed is not None,
            installed_filter_id=installed.id if installed else "",
            installed_filter_condition=installed.condition if installed else "",
            clean_filter_ids=", ".join(
                sorted(
                    f.id for f in filters.filters.values() if f.condition == "clean" and f.slot not in (None, self.slot)
                )
            ),
        )

    def _show_lock(self) -> None:
        if self._world.latch is not None:
            color = LOCKED_COLOR if self.locked else UNLOCKED_COLOR
            p.changeVisualShape(self._world.latch, -1, rgbaColor=list(color), physicsClientId=self._world.client)
