"""Shrinking a failure: move its parameters back to the nominal scenario, one at a time, while it
still fails the same way; what is left is a minimal failing scenario (with its seed).

Greedy, in the space's parameter order, one pass: for each parameter not at its nominal value,
try it at nominal; if that no longer fails, try it halfway to nominal (ranges only; whole numbers
rounded towards nominal). A step is kept when the episode ends in the *same* failure outcome as
the original. At most ``max_steps`` episodes. The seed never moves: the same traffic, less abnormal.

:class:`Shrinker` is a plain state machine (``candidate()`` → run it → ``tell(outcome)``) so that
the engine can run the episodes where it likes, and a resumed search replays the stored steps
through it to reach the same state.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from crossroads.search.space import Parameter


@dataclass(frozen=True)
class Step:
    path: str
    params: dict[str, float]  # the whole candidate


class Shrinker:
    """Shrinks one failure (``params`` failing with ``outcome``) towards ``nominal``."""

    def __init__(self, parameters: list[Parameter], params: Mapping[str, float],
                 nominal: Mapping[str, float], outcome: str, *, max_steps: int) -> None:
        self.parameters = parameters
        self.current = {p.path: float(params[p.path]) for p in parameters}
        self.nominal = {p.path: float(nominal[p.path]) for p in parameters}
        self.outcome = outcome
        self.max_steps = max_steps
        self.steps = 0
        self._queue = [p for p in parameters if self.current[p.path] != self.nominal[p.path]]
        self._halfway = False  # whether the pending candidate is the halfway try
        self._pending: Step | None = None

    def _value(self, p: Parameter, halfway: bool) -> float | None:
        base, now = self.nominal[p.path], self.current[p.path]
        if not halfway:
            return base
        if p.choices is not None:
            return None
        middle = (now + base) / 2.0
        if p.whole:  # rounded towards nominal, and it must still move
            middle = float(math.floor(middle) if now > base else math.ceil(middle))
            if middle in (now, base):
                return None
        return middle

    def candidate(self) -> Step | None:
        """The next candidate to run, or None when shrinking is over."""
        if self._pending is not None:
            return self._pending
        while self._queue and self.steps < self.max_steps:
            p = self._queue[0]
            value = self._value(p, self._halfway)
            if value is None:  # no halfway for this one: next parameter
                self._queue.pop(0)
                self._halfway = False
                continue
            self._pending = Step(p.path, {**self.current, p.path: value})
            return self._pending
        return None

    def tell(self, outcome: str) -> None:
        """The outcome of the pending candidate's episode."""
        step = self._pending
        if step is None:
            raise RuntimeError("no candidate is pending")
        self._pending = None
        self.steps += 1
        if outcome == self.outcome:  # still the same failure: keep the step, next parameter
            self.current = dict(step.params)
            self._queue.pop(0)
            self._halfway = False
        elif self._halfway:  # neither nominal nor halfway fails the same way: it stays
            self._queue.pop(0)
            self._halfway = False
        else:
            self._halfway = True

    @property
    def done(self) -> bool:
        return self.candidate() is None
