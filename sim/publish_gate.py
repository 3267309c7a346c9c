"""When a periodic topic is worth publishing: on every change, and at rest only as a heartbeat.

An arm at rest publishing its joint states 60 times a second makes every subscriber (the AT
server, the planner, a bridge client) wake 60 times a second to learn nothing; on a habitat
computer that is also planning and rendering, that idle traffic is what a motion then queues
behind. At rest the same state is repeated once per ``rest_period`` instead, so a late
subscriber, and a watcher of the topic's liveness, still hear it. The first sample after a
change is always repeated at once: a subscriber that tells rest from two equal samples in a row
(as a halt's measurement does) sees the rest when it begins, not a rest period later.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

__all__ = ["PublishGate"]


@dataclass
class PublishGate:
    """Decides, per sample of a periodic topic, whether to publish it.

    ``tolerance`` is how far any value may move and still count as unchanged (physics leaves
    a resting gripper finger trembling by far less than anything a subscriber acts on).
    """

    rest_period: float
    tolerance: float = 1e-6
    _last: tuple[float, ...] | None = field(default=None, init=False)
    _next_heartbeat: float = field(default=0.0, init=False)
    _repeated: bool = field(default=False, init=False)  # the last sample published went out twice

    def due(self, values: Sequence[float], now: float) -> bool:
        """True if ``values`` at time ``now`` should be published (then it becomes the last one)."""
        sample = tuple(values)
        changed = (
            self._last is None
            or len(sample) != len(self._last)
            or any(abs(a - b) > self.tolerance for a, b in zip(sample, self._last, strict=True))
        )
        if not changed and self._repeated and now < self._next_heartbeat:
            return False
        self._repeated = not changed
        self._last = sample
        self._next_heartbeat = now + self.rest_period
        return True
