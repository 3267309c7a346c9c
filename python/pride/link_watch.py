"""The links of a run's gateway as the run sees them: lost since when, how many commands wait.

The gateway calls :meth:`LinkWatch.update` on its own thread whenever a link (a rosbridge
connection) goes down or up, falls quiet or is heard again, or while down or quiet when its
commands in flight change; that must be quick, so it only notes the state. A quiet link (nothing
heard for a few keepalive intervals, the connection not yet given up) is a lost link from the
moment it was last heard: a held link says nothing else for minutes, and the run must not look
connected meanwhile. The executive's supervisor then asks :meth:`LinkWatch.change`
whether a loss or a recovery is to be recorded (LINK_LOST, LINK_RESTORED), and snapshots read
:meth:`LinkWatch.now` at any time, without the executive's lock.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from datetime import UTC, datetime

from pride.event_payloads import LinkLost, LinkRestored
from pride.systems import LinkState

__all__ = ["LinkWatch", "Links"]


@dataclass(frozen=True)
class Links:
    """All links together: lost (since when, UTC) if any is down or quiet; the commands waiting on
    those; ``quiet``: every such link is still connected, only nothing came from it."""

    lost_since: datetime | None
    in_flight: int
    down: tuple[str, ...]
    quiet: bool = False


class LinkWatch:
    """The latest state of each link of one gateway. Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._links: dict[str, LinkState] = {}
        self._recorded: datetime | None = None  # the loss last recorded (None: none open)

    def update(self, state: LinkState) -> None:
        with self._lock:
            self._links[state.link] = state

    def now(self) -> Links:
        with self._lock:
            down = [s for s in self._links.values() if not s.connected or s.quiet_since is not None]
        if not down:
            return Links(None, 0, ())
        times = [s.lost_since if not s.connected else s.quiet_since for s in down]
        since = min((t for t in times if t is not None), default=None)
        lost_since = datetime.fromtimestamp(since, UTC) if since is not None else datetime.now(UTC)
        quiet = all(s.connected for s in down)
        return Links(lost_since, sum(s.in_flight for s in down), tuple(sorted(s.link for s in down)), quiet)

    def change(self) -> LinkLost | LinkRestored | None:
        """The event to record if the links went down or came back since the last one recorded."""
        links = self.now()
        if (links.lost_since is None) == (self._recorded is None):
            return None
        if links.lost_since is not None:
            self._recorded = links.lost_since
            return LinkLost(
                links=links.down, since=links.lost_since.isoformat(), in_flight=links.in_flight, quiet=links.quiet
            )
        since, self._recorded = self._recorded, None
        assert since is not None
        return LinkRestored(since=since.isoformat(), seconds=round((datetime.now(UTC) - since).total_seconds(), 1))
