"""What crossed the link: bytes and stalls per direction, in total and per connection.

Bytes are counted when the relay delivers them to the far end, so a byte held by an outage or
stalled by a loss counts once it has arrived; bytes lost to a reset never count.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any

from .model import Direction

__all__ = ["ConnectionStats", "LinkStats", "StatsFormatError"]


class StatsFormatError(ValueError):
    """A stats document from a control socket is not what the link sends; ``document`` is it."""

    def __init__(self, document: object, problem: str) -> None:
        super().__init__(f"not a link stats document ({problem}): {str(document)[:200]}")
        self.document = document


@dataclass
class ConnectionStats:
    """One TCP connection through the link; times are seconds since the link became ready."""

    id: int
    peer: str
    opened: float
    closed: float | None = None
    ended_by: str | None = None
    up_bytes: int = 0
    down_bytes: int = 0
    up_stalls: int = 0
    down_stalls: int = 0

    def count(self, direction: Direction, nbytes: int) -> None:
        """Record ``nbytes`` delivered in ``direction``."""
        if direction is Direction.UP:
            self.up_bytes += nbytes
        else:
            self.down_bytes += nbytes

    def stalled(self, direction: Direction) -> None:
        """Record one segment delayed by lost transmissions in ``direction``."""
        if direction is Direction.UP:
            self.up_stalls += 1
        else:
            self.down_stalls += 1


@dataclass
class LinkStats:
    """The link as a whole at one moment; ``connections`` lists every connection it carried."""

    uptime: float
    holding_for: float
    refusing_for: float
    holds: int
    resets: int
    refused: int
    connections: list[ConnectionStats] = field(default_factory=list)

    @property
    def up_bytes(self) -> int:
        """Bytes delivered ground → habitat over all connections."""
        return sum(connection.up_bytes for connection in self.connections)

    @property
    def down_bytes(self) -> int:
        """Bytes delivered habitat → ground over all connections."""
        return sum(connection.down_bytes for connection in self.connections)

    @property
    def up_stalls(self) -> int:
        return sum(connection.up_stalls for connection in self.connections)

    @property
    def down_stalls(self) -> int:
        return sum(connection.down_stalls for connection in self.connections)

    @property
    def open_connections(self) -> list[ConnectionStats]:
        return [connection for connection in self.connections if connection.closed is None]

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready document with the totals next to the per-connection figures."""
        document = asdict(self)
        document.update(
            up_bytes=self.up_bytes, down_bytes=self.down_bytes, up_stalls=self.up_stalls, down_stalls=self.down_stalls
        )
        return document

    @classmethod
    def from_json(cls, document: Any) -> LinkStats:
        """Read back :meth:`to_json` (totals are recomputed, not trusted).

        Raises:
            StatsFormatError: a field is missing or has the wrong type.
        """
        if not isinstance(document, dict) or not isinstance(document.get("connections"), list):
            raise StatsFormatError(document, "no connections list")
        try:
            connections = [
                ConnectionStats(**{f.name: item[f.name] for f in fields(ConnectionStats)})
                for item in document["connections"]
            ]
            link = {f.name: document[f.name] for f in fields(cls) if f.name != "connections"}
        except (KeyError, TypeError) as exc:
            raise StatsFormatError(document, f"missing {exc}") from None
        return cls(**link, connections=connections)
