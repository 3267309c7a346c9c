"""The camera's render budget: frames take at most their share of the simulator's time."""

from __future__ import annotations

import threading

import pytest

from sim.render_budget import RenderBudget


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_after_a_frame_the_next_waits_three_times_as_long_at_a_quarter_duty() -> None:
    clock = Clock()
    budget = RenderBudget(duty=0.25, clock=clock)
    assert budget.take_turn(wait=False)
    assert not budget.take_turn(wait=False), "one frame at a time"
    budget.done(0.4)  # the frame took 0.4 s: 1.2 s must pass before the next
    clock.now += 1.1
    assert not budget.take_turn(wait=False), "a periodic image before its turn is skipped"
    clock.now += 0.15
    assert budget.take_turn(wait=False)


def test_a_requested_capture_waits_for_the_frame_in_progress_and_then_renders() -> None:
    budget = RenderBudget(duty=1.0)  # no spacing: only the frame in progress delays it
    assert budget.take_turn(wait=False)
    took_turn = threading.Event()
    waiter = threading.Thread(target=lambda: budget.take_turn(wait=True) and took_turn.set())
    waiter.start()
    assert not took_turn.wait(0.2), "it must wait while a frame is drawn"
    budget.done(0.0)
    waiter.join(10)
    assert took_turn.is_set()


def test_a_duty_outside_zero_to_one_is_refused() -> None:
    with pytest.raises(ValueError, match="duty must be in"):
        RenderBudget(duty=0)
