"""Telemetry limits, as a SysRep declares them, and how long a value must be out before it counts.

A numeric item has red and yellow bands (``red_low < yellow_low <= yellow_high < red_high``, any of
them left out); an item of another type an ``equals`` that must hold (out of it is red), as COSMOS
and PRIDE state limits. ``persistence`` is how many samples in a row (``3``) or how long (``2 s``)
a value must stay out before it is reported out, so one noisy sample does not halt an arm.

    - [gripper_force, Gripper Force, real, {units: N, limits: {yellow_high: 30, red_high: 40, persistence: 2}}]
    - [grasped, Grasped, boolean, {limits: {equals: true}}]
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

__all__ = ["GREEN", "RED", "YELLOW", "Limits", "Persistence", "parse_limits", "parse_persistence"]

GREEN, YELLOW, RED = "green", "yellow", "red"
_BANDS = ("red_low", "yellow_low", "yellow_high", "red_high")
_PERSISTENCE = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*(s)?\s*$")


@dataclass(frozen=True)
class Persistence:
    """How long a value must stay out of its limits before it counts: samples in a row, or seconds."""

    samples: int = 1
    seconds: float = 0.0

    def describe(self) -> str:
        if self.seconds:
            return f"for {self.seconds:g} s"
        return "" if self.samples == 1 else f"for {self.samples} samples"


def parse_persistence(text: object) -> Persistence:
    """``3`` (samples in a row) or ``"2 s"`` (seconds); ValueError says what is expected."""
    if isinstance(text, bool):
        raise ValueError(f"persistence must be a number of samples (3) or seconds (2 s), got {text!r}")
    if isinstance(text, int) and text >= 1:
        return Persistence(samples=text)
    found = _PERSISTENCE.match(str(text))
    if found is None:
        raise ValueError(f"persistence must be a number of samples (3) or seconds (2 s), got {text!r}")
    number = float(found.group(1))
    if found.group(2):
        if not math.isfinite(number) or number <= 0:
            raise ValueError(f"persistence in seconds must be more than 0, got {text!r}")
        return Persistence(seconds=number)
    if number != int(number) or number < 1:
        raise ValueError(f"persistence in samples must be a whole number of 1 or more, got {text!r}")
    return Persistence(samples=int(number))


@dataclass(frozen=True)
class Limits:
    """A telemetry item's limits: bands of a number, or a value that must hold."""

    red_low: float | None = None
    yellow_low: float | None = None
    yellow_high: float | None = None
    red_high: float | None = None
    equals: Any = None
    persistence: Persistence = Persistence()

    def state(self, value: Any) -> str:
        """:data:`GREEN`, :data:`YELLOW` or :data:`RED` for ``value`` (a value of the wrong kind is red)."""
        if self.equals is not None:
            return GREEN if value == self.equals else RED
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return RED
        if (self.red_low is not None and value < self.red_low) or (self.red_high is not None and value > self.red_high):
            return RED
        if (self.yellow_low is not None and value < self.yellow_low) or (
            self.yellow_high is not None and value > self.yellow_high
        ):
            return YELLOW
        return GREEN

    def describe(self, state: str = RED) -> str:
        """The limit a value at ``state`` is out of, in words: ``red above 40``, ``not true``."""
        if self.equals is not None:
            return f"not {_text(self.equals)}"
        low, high = (self.red_low, self.red_high) if state == RED else (self.yellow_low, self.yellow_high)
        bounds = [f"below {low:g}"] if low is not None else []
        bounds += [f"above {high:g}"] if high is not None else []
        return f"{state} " + " or ".join(bounds)


def parse_limits(data: object, type_name: str, check: Any) -> Limits:
    """A SysRep's ``limits:`` mapping for an item of ``type_name``; ``check(value)`` converts an
    ``equals`` to the item's type. ValueError says what is wrong."""
    if not isinstance(data, dict):
        raise ValueError(f"limits must be a mapping ({', '.join(_BANDS)} or equals), got {data!r}")
    unknown = set(data) - {*_BANDS, "equals", "persistence"}
    if unknown:
        allowed = ", ".join((*_BANDS, "equals", "persistence"))
        raise ValueError(f"limits: unknown key {sorted(unknown)[0]!r} (allowed: {allowed})")
    persistence = parse_persistence(data["persistence"]) if "persistence" in data else Persistence()
    if "equals" in data:
        if set(data) & set(_BANDS):
            raise ValueError("limits: equals or the bands (red_low ... red_high), not both")
        return Limits(equals=check(data["equals"]), persistence=persistence)
    if type_name not in ("integer", "real"):
        raise ValueError(f"limits: bands apply to integer or real items; a {type_name} item states equals")
    bands: dict[str, float] = {}
    for key in _BANDS:
        if key in data:
            value = data[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"limits: {key} must be a finite number, got {value!r}")
            bands[key] = float(value)
    if not bands:
        raise ValueError("limits: state at least one of red_low, yellow_low, yellow_high, red_high, or equals")
    ordered = [bands[k] for k in _BANDS if k in bands]
    if ordered != sorted(ordered):
        raise ValueError(f"limits must rise: red_low < yellow_low <= yellow_high < red_high, got {bands}")
    return Limits(**bands, persistence=persistence)


def _text(value: Any) -> str:
    return ("true" if value else "false") if isinstance(value, bool) else str(value)
