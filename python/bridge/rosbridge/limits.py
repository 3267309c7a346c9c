"""The bridge's quotas and limits: one table of defaults and options, and the counters.

On the habitat, ``caretaker bridge`` is the one service the link reaches, so whatever one client
does must leave the bridge usable for the others: every resource a client can make the bridge
hold is counted per connection and in total, and a request beyond a quota is refused with an
answer naming the limit and its option.  docs/rosbridge.md lists the same table (a test checks
that every option here is documented).
"""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass, field
from typing import Any

from .protocol import OverQuota

MiB = 2**20


def _limit(default: Any, text: str) -> Any:
    return field(default=default, metadata={"help": text})


@dataclass(frozen=True)
class Limits:
    """Every quota and limit of the bridge; each field is the option ``--field-name``."""

    max_connections: int = _limit(64, "WebSocket connections at once; more are refused (HTTP 503)")
    max_subscriptions: int = _limit(256, "subscriptions per connection")
    max_total_subscriptions: int = _limit(512, "subscriptions of all connections")
    max_advertisements: int = _limit(64, "advertised topics, services and actions per connection")
    max_total_advertisements: int = _limit(512, "advertised topics, services and actions of all connections")
    max_calls: int = _limit(64, "service calls in flight per connection")
    max_total_calls: int = _limit(512, "service calls in flight of all connections")
    max_goals: int = _limit(16, "action goals in flight per connection")
    max_total_goals: int = _limit(128, "action goals in flight of all connections")
    max_message_size: int = _limit(
        10_000_000,
        "largest incoming message in bytes, also once reassembled from fragments; a larger frame closes with 1009",
    )
    max_pending_fragments: int = _limit(
        8, "fragmented messages in reassembly per connection (their bytes count against --max-message-size together)"
    )
    max_total_fragment_bytes: int = _limit(64 * MiB, "bytes of fragments in reassembly of all connections")
    fragment_timeout: float = _limit(600.0, "seconds an incomplete fragmented message is kept")
    min_fragment_size: int = _limit(1024, "smallest fragment_size a client may ask for (characters)")
    max_queued_bytes: int = _limit(
        64 * MiB,
        "bytes waiting to be sent to one client: topic messages beyond it "
        "are dropped oldest first, an answer beyond it closes with 1008",
    )
    max_total_queued_bytes: int = _limit(
        512 * MiB,
        "bytes waiting to be sent to all clients: beyond it the client with the most waiting is closed with 1008",
    )
    read_pause_bytes: int = _limit(
        1 * MiB,
        "bytes waiting for one client above which the bridge stops reading "
        "its requests until they are sent (backpressure)",
    )
    handshake_timeout: float = _limit(
        60.0,
        "seconds a client has to finish the TLS and WebSocket opening handshakes; several round trips "
        "of a lossy 1.3 s link, or a starved bridge, need more than websockets' 10 s",
    )
    auth_timeout: float = _limit(20.0, "seconds a client has to authenticate (with --auth-secret-file)")
    login_max_age: float = _limit(
        60.0,
        "seconds a signed login (its t) may be old when it arrives: the clocks' difference and, from "
        "a client far away, its one-way delay",
    )
    ping_interval: float = _limit(30.0, "seconds between keepalive pings (0: none)")
    ping_timeout: float = _limit(
        180.0,
        "seconds without a pong before the connection is closed (1011); longer than the ground's outage "
        "budget (120 s by default) and a ping interval, so a client the ground still waits for is kept (0: never)",
    )

    @staticmethod
    def add_options(parser: argparse.ArgumentParser) -> None:
        """Add ``--max-connections`` etc. to ``parser`` (defaults from this table)."""
        group = parser.add_argument_group("limits (docs/rosbridge.md)")
        for item in dataclasses.fields(Limits):
            kind = float if item.type in ("float", float) else int
            group.add_argument(
                option(item.name),
                dest=item.name,
                type=kind,
                default=item.default,
                metavar="N",
                help=f"{item.metadata['help']} (default {item.default:g})",
            )

    @staticmethod
    def from_args(args: argparse.Namespace) -> Limits:
        return Limits(**{item.name: getattr(args, item.name) for item in dataclasses.fields(Limits)})


def option(name: str) -> str:
    """The command-line option of a :class:`Limits` field."""
    return "--" + name.replace("_", "-")


class Quota:
    """One counted resource (e.g. subscriptions) with a per-connection and a total limit."""

    def __init__(self, what: str, per_connection: int, total: int, per_option: str, total_option: str) -> None:
        self.what = what
        self.per_connection = per_connection
        self.total_limit = total
        self._options = (per_option, total_option)
        self.counts: dict[int, int] = {}
        self.total = 0

    def take(self, session: int, amount: int = 1) -> None:
        """Count ``amount`` more for ``session``, or raise :class:`OverQuota` (nothing counted)."""
        mine = self.counts.get(session, 0)
        if mine + amount > self.per_connection:
            raise OverQuota(
                f"too many {self.what} on this connection (limit {self.per_connection}, {self._options[0]})"
            )
        if self.total + amount > self.total_limit:
            raise OverQuota(f"too many {self.what} on this bridge (limit {self.total_limit}, {self._options[1]})")
        self.counts[session] = mine + amount
        self.total += amount

    def give(self, session: int, amount: int = 1) -> None:
        """Count ``amount`` less for ``session`` (ignored once the session was forgotten)."""
        mine = self.counts.get(session)
        if mine is None:
            return
        amount = min(amount, mine)
        self.total -= amount
        if mine == amount:
            del self.counts[session]
        else:
            self.counts[session] = mine - amount

    def forget(self, session: int) -> None:
        """Drop everything counted for a closed session."""
        self.total -= self.counts.pop(session, 0)


class Quotas:
    """The counted resources of :class:`Limits`."""

    def __init__(self, limits: Limits) -> None:
        def quota(what: str, name: str) -> Quota:
            per, total = getattr(limits, f"max_{name}"), getattr(limits, f"max_total_{name}")
            return Quota(what, per, total, option(f"max_{name}"), option(f"max_total_{name}"))

        self.subscriptions = quota("subscriptions", "subscriptions")
        self.advertisements = quota("advertisements", "advertisements")
        self.calls = quota("service calls in flight", "calls")
        self.goals = quota("action goals in flight", "goals")

    def forget(self, session: int) -> None:
        """Drop the counts of a closed session, except its goals: those count until each goal's
        task has seen it end (a disconnect cancels the goals, see actions.py)."""
        for counted in (self.subscriptions, self.advertisements, self.calls):
            counted.forget(session)
