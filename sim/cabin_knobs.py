"""Two knobs on the cabin's CO2, for a demonstration of an anomaly and its recovery in a minute.

At the cabin's own rates (sim/cabin_air.py) a spent filter takes hours to push the CO2 past the
``cdra`` SysRep's yellow limit (4.0 mmHg), and a filter change moves it by hundredths of a mmHg:
nothing a demonstration could show. ``cabin_start_ppco2`` puts the cabin's CO2 where the story
starts (just under the limit); ``cabin_chemistry_scale`` runs the cabin's chemistry (the crew's CO2,
the filter's removal and its saturation together) that many times faster than sim time. The
robot's motion keeps its pace (``time_scale``), so the same filter change, at the same speed,
is what brings the cabin back.

Both are ROS parameters of the simulation node (``ros2 param set /caretaker_sim
cabin_start_ppco2 3.95``: the cabin's CO2 is put there at once, to tell the story again) and
options of ``caretaker sim``, ``caretaker up`` and ``caretaker demo`` (``--cabin-start-ppco2``,
``--cabin-chemistry-scale``). The demonstration's values are 3.95 mmHg at 30 times: with the IVA
scene's spent filter locked in, the cabin crosses yellow about 7 s of sim time after the start
and would reach red no sooner than 2 minutes later; the IVA procedure at real time keeps the bed
open about 25 s, and the clean filter it locks in brings the cabin back under yellow within 40 s
of the lock (tests/sim/test_cabin_air.py). 60 times cross as fast from 3.9 mmHg and come back
as fast, but leave half the time before red.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping
from dataclasses import dataclass

from sim.cabin_air import START_PPCO2, CabinAir

__all__ = [
    "BY_NAME",
    "CHEMISTRY_SCALE",
    "KNOBS",
    "START",
    "Knob",
    "add_options",
    "command_line",
    "given",
    "knob_named",
    "set_knobs",
]


@dataclass(frozen=True)
class Knob:
    """One setting of the cabin's air: a ROS parameter of the simulation node, the option of the
    same name, and the :class:`CabinAir` attribute it sets."""

    parameter: str
    attribute: str
    minimum: float
    maximum: float  # math.inf: any finite number
    above_minimum: bool  # the minimum itself is refused
    metavar: str
    help: str

    @property
    def option(self) -> str:
        return "--" + self.parameter.replace("_", "-")

    def refusal(self, value: object) -> str | None:
        """Why ``value`` cannot be this knob's, or None when it can (an integer is a number, a bool is not)."""
        if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
            low_ok = value > self.minimum if self.above_minimum else value >= self.minimum
            if low_ok and value <= self.maximum:
                return None
        low = f"{'>' if self.above_minimum else '>='} {self.minimum:g}"
        high = f" and <= {self.maximum:g}" if math.isfinite(self.maximum) else ""
        return f"{self.parameter} must be a number {low}{high}, got {value!r}"

    def parse(self, text: str) -> float:
        """The option's value (argparse's ``type``): a refusal is argparse's error, with its reason."""
        try:
            value: object = float(text)
        except ValueError:
            value = text
        refused = self.refusal(value)
        if refused is not None:
            raise argparse.ArgumentTypeError(refused)
        return float(text)


START = Knob(
    "cabin_start_ppco2",
    "ppco2",
    0.0,
    math.inf,
    False,
    "MMHG",
    f"the cabin's CO2 partial pressure at the start (default {START_PPCO2:g} mmHg; the cdra SysRep's "
    "yellow limit is 4.0): with --cabin-chemistry-scale, an anomaly shown in a minute (sim/README.md)",
)
#: At most an hour of the cabin's chemistry per sim second: its integration steps grow with the scale.
CHEMISTRY_SCALE = Knob(
    "cabin_chemistry_scale",
    "chemistry_scale",
    0.0,
    3600.0,
    True,
    "K",
    "run the cabin's CO2 (the crew's breath, the filter's removal and saturation) K times faster than "
    "sim time, the robot's motion unchanged (default 1; the demonstration of a spent filter: 30 with "
    "--cabin-start-ppco2 3.95)",
)
KNOBS = (START, CHEMISTRY_SCALE)
BY_NAME = {knob.parameter: knob for knob in KNOBS}


def knob_named(name: str) -> Knob:
    """The knob of parameter ``name``.

    Raises:
        ValueError: there is none (a misspelt knob is never silently left out).
    """
    try:
        return BY_NAME[name]
    except KeyError:
        raise ValueError(f"no cabin air knob {name!r}; the knobs are {', '.join(BY_NAME)}") from None


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--cabin-start-ppco2`` and ``--cabin-chemistry-scale``, unset unless given."""
    for knob in KNOBS:
        parser.add_argument(knob.option, type=knob.parse, metavar=knob.metavar, help=knob.help)


def given(args: argparse.Namespace) -> dict[str, float]:
    """The knobs the options of :func:`add_options` set, by parameter name (none given: empty)."""
    values = {knob.parameter: getattr(args, knob.parameter) for knob in KNOBS}
    return {name: value for name, value in values.items() if value is not None}


def command_line(values: Mapping[str, float]) -> list[str]:
    """``caretaker sim``'s options for ``values`` (by parameter name), which it checks."""
    return [arg for name, value in values.items() for arg in (knob_named(name).option, repr(float(value)))]


def set_knobs(air: CabinAir, values: Mapping[str, float]) -> None:
    """Set ``values`` (by parameter name, each checked: :meth:`Knob.refusal`) on ``air``."""
    for name, value in values.items():
        setattr(air, knob_named(name).attribute, float(value))
