"""Slowing down password guessing: after a few failed sign-ins, each further try must wait.

Failures are counted per user id *and* address, per address (one machine trying many users) and
per user id (many machines trying one user). Each key has a number of free failures; past it,
the next try must wait ``2^(n-1)`` seconds after the last failure, up to the key's ceiling. A
success clears the user's counts. Failures older than the window are forgotten, and the ceilings
are minutes, so a real user is delayed, never locked out: someone guessing from one address hits
its pair key long before the per-user key, which has a higher allowance, so the real user
signing in from their own console is not held up by a guesser elsewhere.

Counts live in this server's memory: a restart forgets them (and signs everyone out anyway).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = ["Allowance", "SignInThrottle"]


@dataclass(frozen=True)
class Allowance:
    """How many failures a key gets free, and the longest wait it can be made to take (seconds)."""

    free: int
    max_delay: float


@dataclass
class _Failures:
    times: list[float] = field(default_factory=list)  # of the failures within the window, oldest first


class SignInThrottle:
    """Counts failed sign-ins and says how long the next try must wait. Thread-safe."""

    def __init__(
        self,
        *,
        pair: Allowance = Allowance(5, 60.0),
        address: Allowance = Allowance(20, 300.0),
        user: Allowance = Allowance(20, 60.0),
        window: float = 900.0,
        max_keys: int = 10_000,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._allowances = {"pair": pair, "address": address, "user": user}
        self._window = window
        self._max_keys = max_keys
        self._clock = clock
        self._lock = threading.Lock()  # guards _failures
        self._failures: dict[tuple[str, ...], _Failures] = {}

    @staticmethod
    def _keys(user: str, address: str) -> dict[str, tuple[str, ...]]:
        return {"pair": ("pair", user, address), "address": ("address", address), "user": ("user", user)}

    def wait(self, user: str, address: str) -> float:
        """Seconds before ``user`` may try again from ``address`` (0: now)."""
        now = self._clock()
        with self._lock:
            longest = 0.0
            for name, key in self._keys(user, address).items():
                failures = self._current(key, now)
                allowance = self._allowances[name]
                if failures is None or len(failures.times) < allowance.free:
                    continue
                delay = min(allowance.max_delay, 2.0 ** (len(failures.times) - allowance.free))
                longest = max(longest, failures.times[-1] + delay - now)
            return longest

    def failed(self, user: str, address: str) -> None:
        now = self._clock()
        with self._lock:
            for key in self._keys(user, address).values():
                failures = self._current(key, now) or self._failures.setdefault(key, _Failures())
                failures.times.append(now)
            if len(self._failures) > self._max_keys:  # bounded memory: forget the stalest keys
                for key in sorted(self._failures, key=lambda k: self._failures[k].times[-1])[
                    : len(self._failures) - self._max_keys
                ]:
                    del self._failures[key]

    def succeeded(self, user: str, address: str) -> None:
        """The right password: this user's counts start again (the address's stay)."""
        keys = self._keys(user, address)
        with self._lock:
            self._failures.pop(keys["pair"], None)
            self._failures.pop(keys["user"], None)

    def _current(self, key: tuple[str, ...], now: float) -> _Failures | None:
        """The key's failures within the window (called with the lock held)."""
        failures = self._failures.get(key)
        if failures is None:
            return None
        failures.times = [t for t in failures.times if now - t < self._window]
        if not failures.times:
            del self._failures[key]
            return None
        return failures
