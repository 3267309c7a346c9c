"""Who may connect and what they may touch: allow-lists and client authentication.

Allow-lists are fnmatch globs per kind (topics, services, actions).  An empty list allows
everything; otherwise a name must match one glob, and a refusal is *answered* (failed
``service_response``/``action_result``, or ``status`` after ``set_level``), not only logged.
``/rosapi/*`` is always allowed when a services list is set, as in rosbridge.

Authentication is optional.  With a shared secret configured the first message of every
connection must be an ``auth`` message, either

* ``{"op": "auth", "token": SECRET}`` (a bearer token; use with TLS), or
* ``{"op": "auth", "mac": HEX, "client": C, "dest": D, "rand": R, "t": T, "level": L, "end": E}``
  where HEX = HMAC-SHA256(SECRET, C + D + R + str(T) + L + str(E)) (rosauth's fields), T is
  the client's Unix time in seconds within :data:`MAX_CLOCK_SKEW_S` of the server's, and E the
  end of validity (Unix seconds, not yet passed).

Anything else first, or a wrong token or MAC, closes the connection with 1008 (policy violation).
"""

from __future__ import annotations

import fnmatch
import hashlib
import hmac
import time
from dataclasses import dataclass
from typing import Any

from .protocol import Refused

MAX_CLOCK_SKEW_S = 60.0


@dataclass(frozen=True)
class AllowList:
    """Glob patterns one kind of name must match (empty: everything allowed)."""

    kind: str
    globs: tuple[str, ...] = ()

    def check(self, name: str) -> None:
        """Raise :class:`Refused` unless ``name`` is allowed."""
        if not self.globs or any(fnmatch.fnmatchcase(name, glob) for glob in self.globs):
            return
        if self.kind == "service" and name.startswith("/rosapi/"):
            return
        raise Refused(f"{self.kind} {name} is not allowed by this bridge (allowed: {', '.join(self.globs)})")


def authenticate(message: Any, secret: str) -> None:
    """Raise :class:`Refused` unless ``message`` is a valid ``auth`` message for ``secret``."""
    if not isinstance(message, dict) or message.get("op") != "auth":
        raise Refused("authentication required: the first message must be an auth message")
    if "token" in message:
        if isinstance(message["token"], str) and hmac.compare_digest(message["token"].encode(), secret.encode()):
            return
        raise Refused("authentication failed: wrong token")
    fields = ("mac", "client", "dest", "rand", "t", "level", "end")
    if any(field not in message for field in fields):
        raise Refused(f"authentication failed: an auth message needs a token, or {', '.join(fields)}")
    t, end = message["t"], message["end"]
    if not isinstance(t, (int, float)) or not isinstance(end, (int, float)) or not isinstance(message["mac"], str):
        raise Refused("authentication failed: t and end must be numbers, mac a hex string")
    now = time.time()
    if abs(now - t) > MAX_CLOCK_SKEW_S or end < now:
        raise Refused("authentication failed: the auth message is expired or its clock is off")
    text = "".join(str(message[f]) for f in ("client", "dest", "rand", "t", "level", "end"))
    expected = hmac.new(secret.encode(), text.encode(), hashlib.sha256).hexdigest()
    if not hmac.compare_digest(expected, message["mac"].lower()):
        raise Refused("authentication failed: wrong mac")
