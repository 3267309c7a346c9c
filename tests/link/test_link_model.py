"""The link's values and its TCP model: option checks, RTO, deterministic segment fates."""

from __future__ import annotations

import pytest

from caretaker.link import Direction, DirectionConfig, LinkConfig, LinkOptionError, Outage, OutageKind, TcpModel
from caretaker.link.model import parse_address, parse_outage
from caretaker.link.tcp_model import MAX_TRANSMISSIONS, RTO_MAX, RTO_MIN


def test_outage_specs_parse() -> None:
    assert parse_outage("hold:30@40") == Outage(OutageKind.HOLD, 30.0, 40.0)
    assert parse_outage("reset:2.5@0") == Outage(OutageKind.RESET, 2.5, 0.0)
    assert str(parse_outage("hold:30@40")) == "hold:30@40"


@pytest.mark.parametrize("spec", ["hold:30", "pause:3@1", "hold:x@1", "hold:-1@0", "reset:1@-2", "hold:nan@1", ""])
def test_bad_outage_specs_name_the_spec_and_the_format(spec: str) -> None:
    with pytest.raises(LinkOptionError) as error:
        parse_outage(spec)
    assert error.value.option == "--outage" and error.value.value == spec
    assert "KIND:SECONDS@START" in str(error.value) or "SECONDS and START" in str(error.value)


def test_addresses_parse_and_bad_ones_are_refused() -> None:
    assert parse_address("--to", "10.0.0.2:9090") == ("10.0.0.2", 9090)
    assert parse_address("--to", "[::1]:0") == ("::1", 0)
    for bad in ["9090", "host:", ":9090", "host:70000", "host:-1"]:
        with pytest.raises(LinkOptionError, match="HOST:PORT"):
            parse_address("--to", bad)


@pytest.mark.parametrize(
    "options, option",
    [
        ({"delay": -0.1}, "delay"),
        ({"jitter": float("inf")}, "jitter"),
        ({"loss": 1.0}, "loss"),
        ({"loss": -0.01}, "loss"),
        ({"kbps": 0}, "kbps"),
        ({"kbps": float("nan")}, "kbps"),
    ],
)
def test_direction_values_out_of_range_are_refused(options: dict[str, float], option: str) -> None:
    with pytest.raises(LinkOptionError) as error:
        DirectionConfig(**options)
    assert error.value.option == option


def test_rto_is_the_round_trip_plus_linux_floor_on_the_variance_term() -> None:
    plain = TcpModel(LinkConfig.symmetric(delay=1.3))
    assert plain.rto(Direction.UP) == pytest.approx(2.6 + RTO_MIN)
    jittery = TcpModel(LinkConfig.symmetric(delay=1.3, jitter=0.4))
    # SRTT 2.6 + mean jitter 0.4; RTTVAR a quarter of both spans (0.2): 4 x 0.2 beats the 200 ms floor
    assert jittery.rto(Direction.DOWN) == pytest.approx(3.0 + 0.8)
    slow_uplink = TcpModel(LinkConfig.symmetric(delay=1.3, up_kbps=16))
    assert slow_uplink.rto(Direction.UP) == pytest.approx(2.6 + RTO_MIN + (1448 * 8) / 16_000)
    assert slow_uplink.rto(Direction.DOWN) == pytest.approx(2.6 + RTO_MIN)
    assert TcpModel(LinkConfig.symmetric(delay=100)).rto(Direction.UP) == RTO_MAX


def test_fates_repeat_with_the_seed_and_differ_with_another() -> None:
    def pattern(seed: int) -> list[int]:
        model = TcpModel(LinkConfig.symmetric(loss=0.05, jitter=0.1, seed=seed))
        return [model.fate(Direction.UP, 1, offset * 1448).losses for offset in range(2000)]

    assert pattern(7) == pattern(7)
    assert pattern(7) != pattern(8)
    lost = sum(1 for losses in pattern(7) if losses)
    assert 60 <= lost <= 140, f"{lost} of 2000 segments lost at 5 %"


def test_fates_differ_by_direction_and_connection() -> None:
    model = TcpModel(LinkConfig.symmetric(loss=0.3, seed=1))
    keys = [(direction, connection) for direction in Direction for connection in (1, 2)]
    patterns = {key: [model.fate(*key, offset).losses for offset in range(0, 200 * 100, 100)] for key in keys}
    assert len({tuple(pattern) for pattern in patterns.values()}) == len(keys)


def test_consecutive_losses_double_the_timeout() -> None:
    model = TcpModel(LinkConfig.symmetric(delay=0.5, loss=0.5, seed=3))
    rto = model.rto(Direction.DOWN)
    fates = [model.fate(Direction.DOWN, 1, offset) for offset in range(500)]
    for fate in fates:
        assert fate.stall == pytest.approx(sum(min(RTO_MAX, rto * 2**attempt) for attempt in range(fate.losses)))
    assert {0, 1, 2, 3} <= {fate.losses for fate in fates}
    assert all(fate.jitter == 0.0 for fate in fates)  # no jitter asked, none given


def test_jitter_stays_within_its_span() -> None:
    model = TcpModel(LinkConfig.symmetric(jitter=0.05, seed=2))
    jitters = [model.fate(Direction.UP, 1, offset).jitter for offset in range(1000)]
    assert all(0.0 <= jitter < 0.05 for jitter in jitters)
    assert max(jitters) - min(jitters) > 0.04  # spread over the span, not stuck


def test_a_hopeless_segment_is_retransmitted_a_bounded_number_of_times() -> None:
    model = TcpModel(LinkConfig.symmetric(loss=0.999, seed=0))
    assert model.fate(Direction.UP, 1, 0).losses == MAX_TRANSMISSIONS - 1


def test_link_config_checks_segment_size_and_window() -> None:
    with pytest.raises(LinkOptionError, match="mss"):
        LinkConfig(mss=10)
    with pytest.raises(LinkOptionError, match="window"):
        LinkConfig(window=100)
    config = LinkConfig.symmetric(delay=1.3, up_kbps=16, down_kbps=64, outages=(Outage(OutageKind.HOLD, 30, 40),))
    assert config.round_trip == pytest.approx(2.6)
    assert "16 kbit/s" in config.describe() and "outage hold:30@40" in config.describe()
