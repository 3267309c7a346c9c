"""How fast an agent may call: a burst, then a steady rate, so a runaway or hostile assistant cannot
flood the ground's database or the consoles' lists of proposals.

A token bucket: ``burst`` calls at once, refilled at ``per_second``. A call over the budget is not
queued; it is refused by the rule ``call_rate`` (and recorded as every refusal is), so the agent
learns at once that it must slow down.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = ["CallBudget"]


@dataclass
class CallBudget:
    """One agent session's calls: ``burst`` at once, then ``per_second``. Thread-safe."""

    burst: int = 30
    per_second: float = 2.0
    clock: Callable[[], float] = time.monotonic
    _left: float = field(init=False)
    _at: float = field(init=False)
    _lock: threading.Lock = field(init=False, default_factory=threading.Lock)

    def __post_init__(self) -> None:
        if self.burst < 1 or self.per_second <= 0:
            raise ValueError(
                f"a call budget needs a burst of at least 1 and a positive rate, not {self.burst} and {self.per_second}"
            )
        self._left, self._at = float(self.burst), self.clock()

    def take(self) -> bool:
        """Spend one call; False when none is left now."""
        with self._lock:
            now = self.clock()
            self._left = min(float(self.burst), self._left + (now - self._at) * self.per_second)
            self._at = now
            if self._left < 1:
                return False
            self._left -= 1
            return True

    def describe(self) -> str:
        return f"at most {self.burst} calls at once and {self.per_second:g} a second after that"
