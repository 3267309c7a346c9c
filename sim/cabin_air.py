"""The cabin's CO2 as the CDRA keeps it: the crew breathe it out, the filter locked in the cabinet
takes it out as well as its saturation lets it.

The partial pressure ``p`` (mmHg, as ISS flight rules state CO2) and each filter's saturation
``s`` (0 clean .. 1 full) follow, on sim time::

    dp/dt = GENERATION - removal          removal = REMOVAL_RATE * (1 - s) * p
    ds/dt = removal / CAPACITY            (only for the filter in the bed)

A filter removes only while it is seated in the cabinet and locked: the lock seals the bed (an
unlocked one is open to the cabin), and with no filter there is no bed at all. The rates are a
small habitat's, not a tuned plant model: GENERATION is four crew (about 1 kg CO2 each a day) in
some 60 m3 of free volume, so an IVA filter change (minutes) moves ``p`` by hundredths of a mmHg
while a saturated filter left in place takes the cabin past its red limit within hours.

``chemistry_scale`` runs all of it (the crew's CO2, the removal, the saturation) that many times
faster than sim time, and ``ppco2`` may be put anywhere: a demonstration shows in a minute what the
cabin does in an hour, the robot's motion unchanged (sim/cabin_knobs.py).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

__all__ = [
    "CAPACITY",
    "GENERATION",
    "REMOVAL_RATE",
    "START_PPCO2",
    "CabinAir",
    "initial_saturation",
]

#: mmHg of CO2 the crew add per second (0.02 mmHg a minute: four crew in about 60 m3)
GENERATION = 0.02 / 60.0
#: per second: a clean locked filter holds the cabin at GENERATION / REMOVAL_RATE = 2.0 mmHg
REMOVAL_RATE = GENERATION / 2.0
#: mmHg of cabin CO2 a filter takes up from clean to full (about a day's worth of the crew's CO2)
CAPACITY = 30.0
#: mmHg at the start: the cabin as the ISS usually keeps it (2 to 3 mmHg)
START_PPCO2 = 2.5
#: The saturation of a filter the scene calls anything but clean (``dirty``): nearly spent.
SPENT_SATURATION = 0.9
#: s of sim time per integration step at most: the rates change by far less within one.
MAX_STEP = 1.0


def initial_saturation(condition: str) -> float:
    """How full a filter of the scene's ``condition`` starts: clean is empty, any other nearly full."""
    return 0.0 if condition == "clean" else SPENT_SATURATION


@dataclass
class CabinAir:
    """The cabin's CO2 and every filter's saturation, advanced to each sim time it is told."""

    saturation: dict[str, float]
    ppco2: float = START_PPCO2
    time: float = 0.0
    #: seconds of the cabin's chemistry per second of sim time
    chemistry_scale: float = 1.0
    _bed: str | None = field(default=None, repr=False)

    @classmethod
    def for_filters(cls, filters: Iterable[tuple[str, str]], time: float = 0.0) -> CabinAir:
        """The cabin at ``time`` with the filters ``(id, condition)`` as the scene has them."""
        return cls({fid: initial_saturation(condition) for fid, condition in filters}, time=time)

    def advance(self, now: float, bed: str | None) -> None:
        """Integrate up to sim time ``now`` with ``bed`` (the filter seated and locked in the
        cabinet, or None) removing since the last call; a bed change counts from this call on.
        A change of :attr:`chemistry_scale` counts from the last call."""
        if bed is not None and bed not in self.saturation:
            raise ValueError(f"no filter {bed!r}; the cabin knows {', '.join(sorted(self.saturation))}")
        if now < self.time:
            raise ValueError(f"sim time runs forward: {now} s is before {self.time} s")
        span = (now - self.time) * self.chemistry_scale  # the chemistry's seconds: MAX_STEP bounds those
        steps = math.ceil(span / MAX_STEP)
        for _ in range(steps):
            dt = span / steps
            removal = 0.0
            if self._bed is not None:
                removal = REMOVAL_RATE * (1.0 - self.saturation[self._bed]) * self.ppco2
                self.saturation[self._bed] = min(1.0, self.saturation[self._bed] + removal * dt / CAPACITY)
            self.ppco2 = max(0.0, self.ppco2 + (GENERATION - removal) * dt)
        self.time, self._bed = now, bed
