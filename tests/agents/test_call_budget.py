"""The call budget: a burst at once, then the steady rate, never more than the burst saved up."""

from __future__ import annotations

import pytest

from agent.call_budget import CallBudget


def test_a_burst_then_the_rate_and_idle_time_saves_no_more_than_the_burst() -> None:
    now = [0.0]
    budget = CallBudget(burst=3, per_second=2.0, clock=lambda: now[0])
    assert [budget.take() for _ in range(4)] == [True, True, True, False]
    now[0] += 0.5  # one call's worth
    assert [budget.take(), budget.take()] == [True, False]
    now[0] += 3600.0
    assert [budget.take() for _ in range(4)] == [True, True, True, False]


@pytest.mark.parametrize(("burst", "rate"), [(0, 1.0), (3, 0.0), (3, -1.0)])
def test_a_budget_that_allows_nothing_is_refused(burst: int, rate: float) -> None:
    with pytest.raises(ValueError, match="a call budget needs"):
        CallBudget(burst=burst, per_second=rate)
