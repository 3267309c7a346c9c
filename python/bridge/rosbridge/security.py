"""Who may connect and what they may touch: allow-lists and client authentication.

Allow-lists are fnmatch globs per kind (topics, services, actions, parameters read and
parameters set).  An empty list allows everything (except setting parameters: none unless
listed); otherwise a name must match one glob, and a refusal is *answered* (failed
``service_response``/``action_result``, or a ``status`` message, sent even without
``set_level``), not only logged.  ``/rosapi/*`` and the bridge's own ``/rosbridge/*`` stay
allowed when a services list is set, as in rosbridge; rosapi lists only what the lists allow.

Browsers send an ``Origin`` header, other clients (roslibpy, roslibjs under Node, Java) none.
Only connections without one are accepted unless ``--allow-origin`` names the web pages that
may connect, so a page an operator happens to open cannot drive the bridge.

Authentication is optional.  With a shared secret configured the first message of every
connection must be an ``auth`` message, either

* ``{"op": "auth", "token": SECRET}`` (a bearer token; use with TLS), or
* ``{"op": "auth", "mac": HEX, "client": C, "dest": D, "rand": R, "t": T, "level": L, "end": E}``
  where HEX = HMAC-SHA256(SECRET, C + D + R + str(T) + L + str(E)) (rosauth's fields), T is
  the client's Unix time in seconds, at most :data:`MAX_CLOCK_SKEW_S` ahead of the server's and
  at most ``--login-max-age`` behind it (a login from far away arrives one light time old), and
  E the end of validity (Unix seconds, not yet passed).

A MAC is accepted once: the bridge remembers each one until it could no longer be accepted
anyway (``t`` + the largest age, or ``end`` if earlier), so a recorded auth message cannot be
replayed.  ``t`` and ``end`` must be finite numbers, the other fields strings.

Anything else first, or a wrong token or MAC, closes the connection with 1008 (policy violation).
"""

from __future__ import annotations

import fnmatch
import hmac
import math
import time
from dataclasses import dataclass
from typing import Any

from rosbridge_wire import MAC_FIELDS, login_mac

from .protocol import Refused, client_text

MAX_CLOCK_SKEW_S = 60.0


@dataclass(frozen=True)
class AllowList:
    """Glob patterns one kind of name must match (empty: everything allowed)."""

    kind: str
    globs: tuple[str, ...] = ()
    always: tuple[str, ...] = ()
    """Globs allowed whatever ``globs`` says (the bridge's own services)."""

    def allows(self, name: str) -> bool:
        return (
            not self.globs
            or any(fnmatch.fnmatchcase(name, glob) for glob in self.globs)
            or any(fnmatch.fnmatchcase(name, glob) for glob in self.always)
        )

    def check(self, name: str) -> None:
        """Raise :class:`Refused` unless ``name`` is allowed."""
        if not self.allows(name):
            allowed = ", ".join(g for g in self.globs if g) or "none"
            raise Refused(f"{self.kind} {client_text(name, 120)} is not allowed by this bridge (allowed: {allowed})")


BRIDGE_SERVICES = ("/rosapi/*", "/rosbridge/*")
"""Services the bridge answers itself; allowed whatever ``--services-glob`` says."""


@dataclass(frozen=True)
class Policy:
    """The allow-lists of one bridge (``--*-glob`` options)."""

    topics: AllowList = AllowList("topic")
    services: AllowList = AllowList("service", always=BRIDGE_SERVICES)
    actions: AllowList = AllowList("action")
    params: AllowList = AllowList("parameter")
    """Parameters clients may read (``/node:name``)."""
    set_params: AllowList = AllowList("parameter change", ("",))
    """Parameters clients may set; the default glob matches no name, so none may be set."""


class Authenticator:
    """Checks ``auth`` messages against the shared secret and remembers the MACs used."""

    def __init__(self, secret: str, *, max_age: float = MAX_CLOCK_SKEW_S) -> None:
        """``max_age``: how old a signed login may be when it arrives (``--login-max-age``)."""
        self._secret = secret.encode()
        self._max_age = max_age
        self._used: dict[str, float] = {}  # MAC -> when it stops being acceptable anyway

    def check(self, message: Any) -> None:
        """Raise :class:`Refused` unless ``message`` is a valid, unused ``auth`` message."""
        if not isinstance(message, dict) or message.get("op") != "auth":
            raise Refused("authentication required: the first message must be an auth message")
        if "token" in message:
            token = message["token"]
            if isinstance(token, str) and hmac.compare_digest(token.encode("utf-8", "replace"), self._secret):
                return
            raise Refused("authentication failed: wrong token")
        if any(name not in message for name in ("mac", *MAC_FIELDS)):
            raise Refused(f"authentication failed: an auth message needs a token, or mac, {', '.join(MAC_FIELDS)}")
        t, end, mac = message["t"], message["end"], message["mac"]
        if not all(_finite_number(value) for value in (t, end)):
            raise Refused("authentication failed: t and end must be finite numbers (Unix seconds)")
        if not isinstance(mac, str) or not all(
            isinstance(message[name], str) for name in ("client", "dest", "rand", "level")
        ):
            raise Refused("authentication failed: mac, client, dest, rand and level must be strings")
        now = time.time()
        if t - now > MAX_CLOCK_SKEW_S or now - t > self._max_age or end < now:
            raise Refused("authentication failed: the auth message is expired or its clock is off")
        expected = login_mac(self._secret, message)
        if not hmac.compare_digest(expected.encode(), mac.lower().encode("utf-8", "replace")):
            raise Refused("authentication failed: wrong mac")
        self._forget_expired(now)
        if expected in self._used:
            raise Refused("authentication failed: this mac was already used (replay)")
        self._used[expected] = min(t + self._max_age, end)

    def _forget_expired(self, now: float) -> None:
        for used in [m for m, until in self._used.items() if until < now]:
            del self._used[used]


def _finite_number(value: Any) -> bool:
    """A JSON number a float holds: an integer past a float's range (``10**400``) is no time at all."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False
