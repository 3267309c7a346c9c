"""The cabin's CO2 model (sim/cabin_air.py), judged against the limits the cdra SysRep states, and
its demonstration knobs (sim/cabin_knobs.py)."""

from __future__ import annotations

import argparse
import math
import re

import pytest

from procedure_language.limits import GREEN, RED, YELLOW, Limits
from procedure_language.sysrep import load_sysrep_dir
from sim.cabin_air import GENERATION, START_PPCO2, CabinAir
from sim.cabin_knobs import CHEMISTRY_SCALE, START, Knob, add_options, command_line, given, set_knobs
from support.procedures import REPO

FILTERS = (("CDRA-F-0007", "dirty"), ("CDRA-F-0012", "clean"))
MINUTE, HOUR = 60.0, 3600.0
#: The demonstration's knobs, as sim/cabin_knobs.py and sim/README.md recommend them.
DEMO = {"cabin_start_ppco2": 3.95, "cabin_chemistry_scale": 30}


@pytest.fixture(scope="module")
def limits() -> Limits:
    item = load_sysrep_dir(REPO / "sysrep")["cdra"].telemetry_item("co2_partial_pressure")
    assert item is not None and item.limits is not None
    return item.limits


def test_with_no_filter_locked_in_the_crew_raise_the_co2_at_their_rate() -> None:
    air = CabinAir.for_filters(FILTERS)
    air.advance(10 * MINUTE, None)
    assert air.ppco2 == pytest.approx(START_PPCO2 + GENERATION * 10 * MINUTE)
    # an unlocked filter is no bed: the caller names none, whatever is seated
    air.advance(20 * MINUTE, None)
    assert air.ppco2 == pytest.approx(START_PPCO2 + GENERATION * 20 * MINUTE)
    assert air.saturation == {"CDRA-F-0007": 0.9, "CDRA-F-0012": 0.0}


def test_a_clean_filter_locked_in_brings_the_co2_down_and_saturates_as_it_does() -> None:
    air = CabinAir.for_filters(FILTERS)
    air.advance(0.0, "CDRA-F-0012")
    samples = []
    for minute in range(1, 61):
        air.advance(minute * MINUTE, "CDRA-F-0012")
        samples.append(air.ppco2)
    assert all(later < earlier for earlier, later in zip([START_PPCO2, *samples], samples, strict=False))
    assert 2.0 < samples[-1] < START_PPCO2 - 0.1
    assert 0.0 < air.saturation["CDRA-F-0012"] < 0.1 and air.saturation["CDRA-F-0007"] == 0.9


def test_a_filter_change_stays_green_and_a_spent_filter_left_in_place_reaches_red(limits: Limits) -> None:
    change = CabinAir.for_filters(FILTERS)
    change.advance(0.0, "CDRA-F-0007")
    change.advance(2 * MINUTE, None)  # unlocked, pulled out, placed, the clean one picked, inserted
    change.advance(12 * MINUTE, "CDRA-F-0012")
    assert limits.state(change.ppco2) == GREEN and change.ppco2 > START_PPCO2

    left = CabinAir.for_filters(FILTERS)
    left.advance(0.0, "CDRA-F-0007")
    states = []
    for hour in range(1, 7):
        left.advance(hour * HOUR, "CDRA-F-0007")
        states.append(limits.state(left.ppco2))
    assert states[0] == GREEN and YELLOW in states and states[-1] == RED, states
    assert left.saturation["CDRA-F-0007"] > 0.9


def test_a_change_of_bed_counts_from_the_call_that_reports_it() -> None:
    air = CabinAir.for_filters(FILTERS)
    air.advance(MINUTE, "CDRA-F-0012")  # the minute before: no bed yet
    assert air.ppco2 == pytest.approx(START_PPCO2 + GENERATION * MINUTE)
    air.advance(2 * MINUTE, None)  # the minute before: the clean filter removed CO2
    assert air.ppco2 < START_PPCO2 + GENERATION * 2 * MINUTE


def test_the_result_does_not_depend_on_how_often_the_simulation_asks() -> None:
    once, often = CabinAir.for_filters(FILTERS), CabinAir.for_filters(FILTERS)
    for air in (once, often):
        air.advance(0.0, "CDRA-F-0007")
    once.advance(HOUR, "CDRA-F-0007")
    for quarter in range(1, 14401):
        often.advance(quarter / 4, "CDRA-F-0007")
    assert once.ppco2 == pytest.approx(often.ppco2, rel=1e-5)  # 1 s steps against 0.25 s ones
    assert once.ppco2 > START_PPCO2 + 0.5  # and the hour changed it


def test_an_unknown_filter_or_time_running_back_is_refused() -> None:
    air = CabinAir.for_filters(FILTERS, time=5.0)
    with pytest.raises(ValueError, match="no filter 'CDRA-F-9999'; the cabin knows CDRA-F-0007, CDRA-F-0012"):
        air.advance(6.0, "CDRA-F-9999")
    with pytest.raises(ValueError, match="sim time runs forward: 4.0 s is before 5.0 s"):
        air.advance(4.0, None)


def test_the_chemistry_scale_runs_the_crew_the_filter_and_its_saturation_that_many_times_faster() -> None:
    fast, slow = CabinAir.for_filters(FILTERS), CabinAir.for_filters(FILTERS)
    fast.chemistry_scale = 60.0
    for air in (fast, slow):
        air.advance(0.0, "CDRA-F-0007")
    fast.advance(MINUTE, "CDRA-F-0007")
    slow.advance(HOUR, "CDRA-F-0007")
    assert fast.ppco2 == pytest.approx(slow.ppco2) and fast.ppco2 > START_PPCO2 + 0.5
    assert fast.saturation == pytest.approx(slow.saturation) and fast.saturation["CDRA-F-0007"] > 0.9
    fast.chemistry_scale = 1.0  # from the last advance on
    fast.advance(2 * MINUTE, None)
    slow.advance(HOUR + MINUTE, None)
    assert fast.ppco2 == pytest.approx(slow.ppco2)


def _states(air: CabinAir, limits: Limits, start: int, end: int, bed: str | None) -> list[str]:
    """The cabin's limit state at each sim second from ``start`` + 1 to ``end``, ``bed`` locked in:
    what the node's samples, a sim second apart, show."""
    states = []
    for second in range(start + 1, end + 1):
        air.advance(float(second), bed)
        states.append(limits.state(air.ppco2))
    return states


def _spent_past_yellow(limits: Limits) -> tuple[CabinAir, list[str]]:
    """The demonstration's cabin with the spent filter locked in, a sim second at a time until it
    is past yellow (a minute at most): the cabin and its states."""
    air = CabinAir.for_filters(FILTERS)
    set_knobs(air, DEMO)
    air.advance(0.0, "CDRA-F-0007")
    states = [limits.state(air.ppco2)]
    while YELLOW not in states and len(states) <= 60:
        states += _states(air, limits, len(states) - 1, len(states), "CDRA-F-0007")
    return air, states


def test_with_the_demonstration_knobs_a_spent_filter_takes_the_cabin_past_yellow_in_seconds(limits: Limits) -> None:
    """And to red no sooner than 2 minutes later, if the filter is left in: time to act on it."""
    air, states = _spent_past_yellow(limits)
    crossed = len(states) - 1
    assert states[0] == GREEN and 5 <= crossed <= 10, states
    left = _states(air, limits, crossed, crossed + 180, "CDRA-F-0007")
    assert set(left[:120]) == {YELLOW} and left[-1] == RED, left


@pytest.mark.parametrize(("change", "back_within"), [(30, 40), (60, 65)])
def test_with_the_demonstration_knobs_a_filter_change_brings_the_cabin_back_in_about_a_minute(
    limits: Limits, change: int, back_within: int
) -> None:
    """The robot unlocks the spent filter 10 s after yellow and locks a clean one in ``change`` s
    later (30 s: about the IVA procedure's pull, place, pick and insert at real time): the cabin
    stays out of red and is back in green within ``back_within`` s of the lock."""
    air, _ = _spent_past_yellow(limits)
    unlocked = int(air.time) + 10
    spent = _states(air, limits, int(air.time), unlocked, "CDRA-F-0007")
    open_bed = _states(air, limits, unlocked, unlocked + change, None)
    clean = _states(air, limits, unlocked + change, unlocked + change + back_within, "CDRA-F-0012")
    assert set(spent + open_bed) == {YELLOW} and clean[-1] == GREEN and RED not in clean, (open_bed, clean)


@pytest.mark.parametrize(
    ("knob", "value", "reason"),
    [
        (START, -1.0, "cabin_start_ppco2 must be a number >= 0, got -1.0"),
        (START, math.nan, "cabin_start_ppco2 must be a number >= 0, got nan"),
        (START, math.inf, "cabin_start_ppco2 must be a number >= 0, got inf"),
        (START, True, "cabin_start_ppco2 must be a number >= 0, got True"),
        (START, "high", "cabin_start_ppco2 must be a number >= 0, got 'high'"),
        (CHEMISTRY_SCALE, 0, "cabin_chemistry_scale must be a number > 0 and <= 3600, got 0"),
        (CHEMISTRY_SCALE, 3600.5, "cabin_chemistry_scale must be a number > 0 and <= 3600, got 3600.5"),
        (CHEMISTRY_SCALE, -math.inf, "cabin_chemistry_scale must be a number > 0 and <= 3600, got -inf"),
    ],
)
def test_a_knob_out_of_its_range_is_refused_with_the_reason(knob: Knob, value: object, reason: str) -> None:
    assert knob.refusal(value) == reason
    with pytest.raises(argparse.ArgumentTypeError, match=f"^{re.escape(reason.partition(', got')[0])}, got "):
        knob.parse(str(value))  # as an option's text: the same reason


def test_the_knobs_as_options_and_as_the_command_line_of_the_simulation() -> None:
    assert START.refusal(0) is None and CHEMISTRY_SCALE.refusal(60) is None and CHEMISTRY_SCALE.refusal(3600.0) is None
    parser = argparse.ArgumentParser()
    add_options(parser)
    assert given(parser.parse_args([])) == {}
    values = given(parser.parse_args(["--cabin-chemistry-scale", "60", "--cabin-start-ppco2", "3.9"]))
    assert values == {"cabin_start_ppco2": 3.9, "cabin_chemistry_scale": 60.0}
    assert command_line(values) == ["--cabin-start-ppco2", "3.9", "--cabin-chemistry-scale", "60.0"]
    with pytest.raises(ValueError, match="^no cabin air knob 'cabin_ppco2'; the knobs are cabin_start_ppco2, "):
        command_line({"cabin_ppco2": 3.9})
