"""The cabin's CO2 model (sim/cabin_air.py), judged against the limits the cdra SysRep states."""

from __future__ import annotations

import pytest

from procedure_language.limits import GREEN, RED, YELLOW, Limits
from procedure_language.sysrep import load_sysrep_dir
from sim.cabin_air import GENERATION, START_PPCO2, CabinAir
from support.procedures import REPO

FILTERS = (("CDRA-F-0007", "dirty"), ("CDRA-F-0012", "clean"))
MINUTE, HOUR = 60.0, 3600.0


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
