"""Light time as a parameter: every wait that spans the link, derived from its one-way delay.

A ground and a habitat may be a light-second apart (the Moon), minutes (Mars), or hours through a
relay that stores and forwards. No wait across the link is a constant: each is a base for the work
at the far end plus the round trips the exchange needs, so the same code holds at 1.3 s and at
20 minutes. The rule (docs/deployment.md, "Light time"):

- opening a connection takes three round trips (TCP, TLS 1.3, the WebSocket upgrade), and a login
  and a first answer one more: :attr:`LightTime.connect_within` allows one round trip more than that;
  a request that may be sent again (an onboard unit, a request for events) goes right behind the
  login instead of waiting for that first answer, so it reaches the far end 3.5 round trips after
  the connection was opened;
- a request is answered within its work plus one round trip (:meth:`LightTime.answer_within`);
- a keepalive ping goes every four one-way delays (at least 5 s) and is given up a round trip after
  the next one was due;
- a ground following an onboard run sends a request for its events every half round trip (at
  least 0.25 s, at most 10 s), each waiting on the habitat three of those: one waits there whenever
  an event happens (:attr:`LightTime.follow_every`, :attr:`LightTime.follow_wait`);
- a signed login stays valid for its trip across the link and then as long as on a short one
  (:attr:`LightTime.login_lifetime`); what goes up over a new connection (an onboard unit and the
  approvals it carries) arrives after opening it and one delay (:attr:`LightTime.uplink_within`);
- the far end allows a client the same: the bridge's handshake and login limits, and the age of a
  signed login it accepts (:meth:`LightTime.bridge_limits`), are never shorter than the delays its
  clients are bound to.
"""

from __future__ import annotations

from dataclasses import dataclass

from rosbridge_wire import LOGIN_LIFETIME_S

__all__ = ["LightTime"]

#: What one exchange may take at the far end, with no light time at all (a loaded machine).
BASE_S = 10.0
#: Round trips to open a wss:// connection and hear the first answer: TCP, TLS, upgrade, login.
OPENING_ROUND_TRIPS = 4
#: The shortest and longest time between a ground's requests for an onboard run's events: no busier
#: than four a second on a short link; on a long one three within the habitat's longest wait (30 s).
FOLLOW_EVERY_S = (0.25, 10.0)


@dataclass(frozen=True)
class LightTime:
    """A link's one-way delay (s) and what it makes of every wait across it."""

    one_way_delay: float = 0.0

    @property
    def round_trip(self) -> float:
        return 2 * self.one_way_delay

    @property
    def connect_within(self) -> float:
        """How long opening a connection and hearing its first answer may take (one round trip spare)."""
        return BASE_S + (OPENING_ROUND_TRIPS + 1) * self.round_trip

    def answer_within(self, work: float = BASE_S) -> float:
        """How long a request whose far end works up to ``work`` s may wait for its answer."""
        return work + self.round_trip

    @property
    def follow_every(self) -> float:
        """Seconds between a ground's requests for an onboard run's events, whatever comes back: half
        a round trip. The habitat keeps the newest waiting, so the run's end comes down at once
        whatever the interval; an event before it waits at most an interval more (and each
        answer carries the executive's state: the interval is what the downlink pays for it)."""
        least, most = FOLLOW_EVERY_S
        return min(max(self.round_trip / 2, least), most)

    @property
    def follow_wait(self) -> float:
        """How long each of those requests waits on the habitat for an event: three intervals, so
        another has arrived before it gives up even when the ground sends it an interval late (busy
        storing what came); the habitat holds three at a time, not more."""
        return 3 * self.follow_every

    @property
    def uplink_within(self) -> float:
        """How long what is sent up as soon as a connection opens may take to arrive: opening it, one way."""
        return self.connect_within + self.one_way_delay

    @property
    def login_lifetime(self) -> float:
        """Seconds a signed login is valid from its signing: it arrives one delay old."""
        return LOGIN_LIFETIME_S + self.one_way_delay

    @property
    def keepalive(self) -> float:
        """Seconds between keepalive pings: never a burden on a long link, never idle on a short one."""
        return max(5.0, 4 * self.one_way_delay)

    @property
    def keepalive_timeout(self) -> float:
        """Seconds without a pong before a connection is given up."""
        return self.keepalive + self.round_trip + BASE_S

    def bridge_limits(self) -> dict[str, float]:
        """The least ``--handshake-timeout``, ``--auth-timeout``, ``--ping-timeout`` and
        ``--login-max-age`` a bridge may give clients this far away: the opening handshakes take
        three round trips, the login comes a round trip after the upgrade's answer, a pong a round
        trip after its ping, and a signed login is one delay old when it arrives."""
        return {
            "handshake_timeout": self.connect_within,
            "auth_timeout": BASE_S + 2 * self.round_trip,
            "ping_timeout": self.keepalive_timeout + self.round_trip,
            "login_max_age": self.login_lifetime,
        }
