"""Browser connections waiting for news: woken from any thread, each on its own asyncio loop.

A run's state changes on the executive's thread (a run hosted here) or the change feed's (a run
hosted elsewhere); the WebSockets that show it wait on asyncio. :meth:`Watchers.wake` is the one
thread boundary (``loop.call_soon_threadsafe``).
"""

from __future__ import annotations

import asyncio
import contextlib
import threading

from console.accounts import Account

__all__ = ["Watcher", "Watchers"]


class Watcher:
    """One browser connection: who it is, and its wake-up flag, set when what it shows changed."""

    def __init__(self, loop: asyncio.AbstractEventLoop, account: Account) -> None:
        self.loop = loop
        self.account = account
        self.changed = asyncio.Event()
        self.sent_seq = 0


class Watchers:
    """The connections watching one thing (a run, the runs list)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._watchers: set[Watcher] = set()

    def add(self, account: Account) -> Watcher:
        """A new watcher on the running loop, woken at once (its first message is the whole state)."""
        watcher = Watcher(asyncio.get_running_loop(), account)
        watcher.changed.set()
        with self._lock:
            self._watchers.add(watcher)
        return watcher

    def remove(self, watcher: Watcher) -> None:
        with self._lock:
            self._watchers.discard(watcher)

    def __len__(self) -> int:
        with self._lock:
            return len(self._watchers)

    def wake(self) -> None:
        with self._lock:
            watchers = list(self._watchers)
        for watcher in watchers:
            with contextlib.suppress(RuntimeError):  # that connection's loop closed: it is going away
                watcher.loop.call_soon_threadsafe(watcher.changed.set)

    def people(self) -> list[dict[str, str]]:
        """Who is watching (each person once), by user id."""
        with self._lock:
            accounts = {w.account.user: w.account for w in self._watchers}
        return [{"user": a.user, "name": a.name, "role": a.role.value} for _, a in sorted(accounts.items())]
