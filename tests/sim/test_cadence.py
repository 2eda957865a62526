"""The world's rules look once per period of simulated time."""

from crossroads.sim.cadence import Every


def test_due_at_the_first_call_then_once_per_period() -> None:
    every = Every(0.5)
    due = [t / 10 for t in range(12) if every.due(t / 10)]
    assert due == [0.0, 0.5, 1.0]  # 0.1-s steps: 0.5 and 1.0 despite float sums


def test_a_late_call_starts_the_next_period_from_itself() -> None:
    every = Every(0.5)
    assert every.due(0.0) and every.due(0.7) and not every.due(1.1) and every.due(1.2)
