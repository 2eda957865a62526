"""How often the world's rules look: once per period of simulated time."""

from __future__ import annotations


class Every:
    """:meth:`due` is true at the first call and then at the first call at least ``period_s`` [s]
    of simulated time after the last true one (the rules step with SUMO, 0.1 s at a time)."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._next_s = 0.0

    def due(self, now_s: float) -> bool:
        if now_s + 1e-9 < self._next_s:
            return False
        self._next_s = now_s + self.period_s
        return True
