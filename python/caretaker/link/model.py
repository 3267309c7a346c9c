"""What a link is: per-direction delay, jitter, loss and bandwidth, and its outages.

Plain values, checked when built, so the relay, the command line and a test all describe a
link the same way and a bad value is refused before anything listens.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from enum import Enum

__all__ = [
    "Direction",
    "DirectionConfig",
    "LinkConfig",
    "LinkOptionError",
    "Outage",
    "OutageKind",
    "parse_address",
    "parse_outage",
]

#: TCP payload per segment on a 1500-byte Ethernet MTU with timestamps (what Linux sends).
DEFAULT_MSS = 1448
#: Bytes of IP and TCP header that travel with each segment and cost bandwidth.
SEGMENT_OVERHEAD = 52
#: Bytes one direction of a connection may have in flight (Linux's default largest receive window, 6 MiB).
DEFAULT_WINDOW = 6 * 1024 * 1024


class LinkOptionError(ValueError):
    """A link option is out of range or malformed; ``option`` and ``value`` name what to fix."""

    def __init__(self, option: str, value: object, expected: str) -> None:
        super().__init__(f"{option} {value!r}: expected {expected}")
        self.option = option
        self.value = value
        self.expected = expected


def _finite(option: str, value: float, *, low: float, high: float = math.inf, closed_high: bool = True) -> None:
    ok = math.isfinite(value) and low <= value and (value <= high if closed_high else value < high)
    if not ok:
        bound = f"<= {high:g}" if closed_high else f"< {high:g}"
        raise LinkOptionError(option, value, f"a number >= {low:g}" + ("" if high == math.inf else f" and {bound}"))


class Direction(Enum):
    """Which way bytes cross: up from the accepting (ground) side to the target, down back."""

    UP = "up"
    DOWN = "down"


@dataclass(frozen=True)
class DirectionConfig:
    """One direction of the link (uplink ground→habitat or downlink habitat→ground).

    ``delay`` is the least one-way time in seconds (light time: nothing arrives sooner);
    ``jitter`` adds up to that many seconds more, uniformly, without reordering; ``loss`` is the
    probability that a TCP segment (and each retransmission of it) is lost; ``kbps`` limits the
    bit rate, headers included (None: no limit).
    """

    delay: float = 0.0
    jitter: float = 0.0
    loss: float = 0.0
    kbps: float | None = None

    def __post_init__(self) -> None:
        _finite("delay", self.delay, low=0.0)
        _finite("jitter", self.jitter, low=0.0)
        _finite("loss", self.loss, low=0.0, high=1.0, closed_high=False)
        if self.kbps is not None and not (math.isfinite(self.kbps) and self.kbps > 0):
            raise LinkOptionError("kbps", self.kbps, "a bit rate > 0 in kbit/s")

    def serialisation(self, nbytes: int) -> float:
        """Seconds the line is busy sending ``nbytes`` (0 without a bandwidth limit)."""
        return 0.0 if self.kbps is None else nbytes * 8 / (self.kbps * 1000)


class OutageKind(Enum):
    """What an outage does to the connections that cross the link."""

    HOLD = "hold"
    """Nothing is sent for the outage's length; connections stay up and bytes arrive after it."""
    RESET = "reset"
    """Every connection is reset (RST to both ends) and new ones are refused for its length."""


@dataclass(frozen=True)
class Outage:
    """An outage of ``seconds`` starting ``at`` seconds after the link is ready."""

    kind: OutageKind
    seconds: float
    at: float = 0.0

    def __post_init__(self) -> None:
        _finite("outage seconds", self.seconds, low=0.0)
        _finite("outage start", self.at, low=0.0)

    def __str__(self) -> str:
        return f"{self.kind.value}:{self.seconds:g}@{self.at:g}"


_OUTAGE = re.compile(r"^(?P<kind>[a-z]+):(?P<seconds>[^@]+)@(?P<at>.+)$")


def parse_outage(spec: str) -> Outage:
    """``KIND:SECONDS@START``, e.g. ``hold:30@40`` (hold 30 s, 40 s after ready).

    Raises:
        LinkOptionError: the spec is malformed or a number is out of range.
    """
    match = _OUTAGE.match(spec.strip())
    expected = "KIND:SECONDS@START with KIND hold or reset, e.g. hold:30@40"
    if match is None:
        raise LinkOptionError("--outage", spec, expected)
    kinds = {kind.value: kind for kind in OutageKind}
    if match["kind"] not in kinds:
        raise LinkOptionError("--outage", spec, expected)
    try:
        seconds, at = float(match["seconds"]), float(match["at"])
    except ValueError:
        raise LinkOptionError("--outage", spec, expected) from None
    try:
        return Outage(kinds[match["kind"]], seconds, at)
    except LinkOptionError as exc:
        raise LinkOptionError("--outage", spec, exc.expected.replace("a number", "SECONDS and START")) from None


def parse_address(option: str, text: str) -> tuple[str, int]:
    """``HOST:PORT`` (IPv6 in brackets) → (host, port); port 0 lets the system pick one.

    Raises:
        LinkOptionError: no port, or a port outside 0..65535.
    """
    host, sep, port = text.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise LinkOptionError(option, text, "HOST:PORT, e.g. 127.0.0.1:9091")
    return host, int(port)


@dataclass(frozen=True)
class LinkConfig:
    """The whole link: both directions, the seed of its random draws and its scheduled outages."""

    up: DirectionConfig = field(default_factory=DirectionConfig)
    down: DirectionConfig = field(default_factory=DirectionConfig)
    seed: int = 0
    outages: tuple[Outage, ...] = ()
    mss: int = DEFAULT_MSS
    window: int = DEFAULT_WINDOW

    def __post_init__(self) -> None:
        if not 64 <= self.mss <= 65_535:
            raise LinkOptionError("mss", self.mss, "a segment size from 64 to 65535 bytes")
        if self.window < self.mss:
            raise LinkOptionError("window", self.window, f"at least one segment ({self.mss} bytes)")

    @classmethod
    def symmetric(
        cls,
        *,
        delay: float = 0.0,
        jitter: float = 0.0,
        loss: float = 0.0,
        up_kbps: float | None = None,
        down_kbps: float | None = None,
        seed: int = 0,
        outages: tuple[Outage, ...] = (),
    ) -> LinkConfig:
        """The same delay, jitter and loss both ways, with a bandwidth per direction."""
        return cls(
            DirectionConfig(delay, jitter, loss, up_kbps),
            DirectionConfig(delay, jitter, loss, down_kbps),
            seed,
            outages,
        )

    def direction(self, which: Direction) -> DirectionConfig:
        """The settings of one direction."""
        return self.up if which is Direction.UP else self.down

    @property
    def round_trip(self) -> float:
        """The least round-trip time: both one-way delays."""
        return self.up.delay + self.down.delay

    def describe(self) -> str:
        """One line for logs and the READY line."""

        def one(direction: DirectionConfig) -> str:
            rate = "unlimited" if direction.kbps is None else f"{direction.kbps:g} kbit/s"
            return f"delay {direction.delay:g} s jitter {direction.jitter:g} s loss {direction.loss * 100:g}% {rate}"

        text = f"up: {one(self.up)}; down: {one(self.down)}; seed {self.seed}"
        return text + "".join(f"; outage {outage}" for outage in self.outages)
