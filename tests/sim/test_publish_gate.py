"""PublishGate: every change goes out, a resting state only as a heartbeat."""

from __future__ import annotations

from sim.publish_gate import PublishGate


def test_the_first_sample_and_every_change_are_due() -> None:
    gate = PublishGate(rest_period=1.0)
    assert gate.due([0.0, 1.0], 0.0)
    assert gate.due([0.0, 1.1], 0.01)
    assert gate.due([0.0, 1.1, 2.0], 0.02)  # a frame more: a change


def test_a_resting_sample_repeats_once_at_once_then_once_per_rest_period() -> None:
    gate = PublishGate(rest_period=1.0)
    assert gate.due([0.5], 0.0)
    assert gate.due([0.5], 1 / 60)  # two equal samples in a row: the rest is seen as it begins
    assert [gate.due([0.5], t / 60) for t in range(2, 61)] == [False] * 59
    assert gate.due([0.5], 61 / 60)  # a rest period after the repeat
    assert not gate.due([0.5], 1.5)


def test_trembling_within_tolerance_is_rest_and_beyond_it_is_motion() -> None:
    gate = PublishGate(rest_period=1.0, tolerance=1e-6)
    assert gate.due([0.5], 0.0)
    assert gate.due([0.5 + 5e-7], 0.05)  # the repeat after a change
    assert not gate.due([0.5 + 5e-7], 0.1)
    assert gate.due([0.5 + 2e-6], 0.2)
    assert gate.due([0.5 + 2e-6], 0.21)
    # the heartbeat restarts from the last sample published
    assert not gate.due([0.5 + 2e-6], 1.2)
    assert gate.due([0.5 + 2e-6], 1.21)
