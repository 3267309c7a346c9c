"""How TCP makes a lossy, jittery link visible to the applications at its ends.

The relay carries byte streams, so it cannot drop bytes: TCP would retransmit them. What an
application sees of a lost segment is a stall: that segment, and every byte behind it on the
same connection and direction (TCP delivers in order), arrives one retransmission timeout (RTO)
late, later still if the retransmission is lost too. This module decides, deterministically from
the link's seed, each segment's fate: its extra delay within the jitter and how many of its
transmissions are lost. A fate depends only on the seed, the connection's number, the direction
and the segment's first byte offset, so the same bytes cut into the same segments meet the same
losses: the relay makes a segment of each piece it reads, cut at multiples of the MSS, which is
each message of an interactive sender (rosbridge frames) and full segments of a bulk transfer.

RTO as Linux computes it (RFC 6298 with Linux's floor on the variance term):
``RTO = SRTT + max(4·RTTVAR, 200 ms)``, at most 120 s, doubled for each consecutive loss of the
same segment. With no measured samples to smooth, SRTT is the link's own round trip (both
one-way delays, the mean jitter of both directions, and the time to serialise one full segment
in the sending direction) and RTTVAR the mean deviation of the jitter (a quarter of each
direction's jitter span).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

from .model import Direction, LinkConfig

__all__ = ["RTO_MAX", "RTO_MIN", "MAX_TRANSMISSIONS", "SegmentFate", "TcpModel"]

RTO_MIN = 0.2
RTO_MAX = 120.0
#: Transmissions of one segment before we deliver it anyway (Linux gives up after tcp_retries2 = 15
#: retransmissions and resets the connection; the emulator keeps it, see docs/link.md).
MAX_TRANSMISSIONS = 16


@dataclass(frozen=True)
class SegmentFate:
    """What the link does to one segment: extra one-way delay, lost transmissions, total stall."""

    jitter: float
    losses: int
    stall: float


def _draw(seed: int, *key: object) -> float:
    """A uniform number in [0, 1) that depends only on the seed and the key.

    A hash rather than a running generator: a segment's fate must not depend on how the
    operating system happened to chunk the bytes before it, nor on other connections' traffic.
    """
    digest = hashlib.blake2b(repr((seed, *key)).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "big") / 2**64


class TcpModel:
    """Deterministic per-segment fates and the RTO of each direction of one link."""

    def __init__(self, config: LinkConfig) -> None:
        self.config = config

    def rto(self, direction: Direction) -> float:
        """The first retransmission timeout of a segment sent in ``direction``."""
        up, down = self.config.up, self.config.down
        srtt = up.delay + down.delay + (up.jitter + down.jitter) / 2
        srtt += self.config.direction(direction).serialisation(self.config.mss)
        rttvar = (up.jitter + down.jitter) / 4
        return min(RTO_MAX, srtt + max(4 * rttvar, RTO_MIN))

    def fate(self, direction: Direction, connection: int, offset: int) -> SegmentFate:
        """The fate of the segment starting at byte ``offset`` of ``connection``'s ``direction``."""
        settings = self.config.direction(direction)
        seed = self.config.seed
        jitter = settings.jitter * _draw(seed, "jitter", direction.value, connection, offset)
        losses, stall, timeout = 0, 0.0, self.rto(direction)
        while (
            losses < MAX_TRANSMISSIONS - 1
            and settings.loss > 0
            and _draw(seed, "loss", direction.value, connection, offset, losses) < settings.loss
        ):
            losses += 1
            stall += timeout
            timeout = min(RTO_MAX, timeout * 2)
        return SegmentFate(jitter, losses, stall)
