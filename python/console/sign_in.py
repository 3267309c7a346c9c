"""Signed-in browsers: sessions with a password check, limits on their life, and a CSRF token each.

A session is a random token in an HttpOnly, SameSite=Strict cookie (Secure under TLS), mapped here
to the account and to a second random token, the CSRF token, which the page sends back in a
header with every state-changing request: another site can make the browser send the cookie
(SameSite aside), never read the token. Sessions end when idle for ``idle`` seconds (no request
and no live connection: an open console stays signed in), ``absolute`` seconds after sign-in
whatever happens, on sign-out, and as soon as the account's password changes or the account is
removed: the ground database announces every change of an account to every console
(:mod:`ground.change_feed`, :meth:`SignIns.notice`), whose next check of that user's
sessions (each request, and each second on an open connection) reads the account again; without
an announcement, sessions are checked against the database every ``recheck`` seconds anyway.

Sessions live in this server's memory, per console: restarting the server signs everyone out,
which is what a restarted ground station should do, and signing in at one console signs in there
only. Accounts, and so the end of sessions, are shared through the database.
"""

from __future__ import annotations

import collections
import math
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from starlette.requests import HTTPConnection

from console.accounts import Account, AccountStore
from console.sign_in_throttle import SignInThrottle
from ground.change_feed import ChangeNotice

__all__ = ["COOKIE", "CSRF_HEADER", "SessionLimits", "SignInRefused", "SignIns", "WebSession"]

COOKIE = "caretaker_session"
CSRF_HEADER = "X-CSRF-Token"
_ENDED_KEPT = 1000  # reasons of ended sessions remembered


@dataclass(frozen=True)
class SessionLimits:
    """How long a session may live (seconds): since its last use, and at all."""

    idle: float = 30 * 60.0
    absolute: float = 12 * 3600.0
    recheck: float = 5.0  # how stale the account (role, password, existence) may be


class SignInRefused(Exception):
    """No session: ``status`` 401 (wrong user or password, session ended) or 429 (wait ``retry_after`` s)."""

    def __init__(self, status: int, message: str, retry_after: int | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.message = message
        self.retry_after = retry_after


@dataclass
class WebSession:
    """One signed-in browser."""

    token: str
    csrf: str
    account: Account
    created: float
    last_used: float
    checked: float

    def csrf_matches(self, token: str | None) -> bool:
        return token is not None and secrets.compare_digest(token.encode(), self.csrf.encode())


class SignIns:
    """Passwords checked against the account store; sessions kept, limited and ended."""

    def __init__(
        self,
        store: AccountStore,
        *,
        limits: SessionLimits = SessionLimits(),
        throttle: SignInThrottle | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.store = store
        self.limits = limits
        self.throttle = throttle or SignInThrottle(clock=clock)
        self._clock = clock
        self._lock = threading.Lock()  # guards _sessions and _ended
        self._sessions: dict[str, WebSession] = {}
        # why recent sessions ended, so every request of a page that is still open gets the same
        # reason, not only the first one to notice (oldest dropped first)
        self._ended: collections.OrderedDict[str, str] = collections.OrderedDict()

    def sign_in(self, user: str, password: str, address: str) -> WebSession:
        """A new session, or SignInRefused (never saying whether the user id or the password was wrong).

        Blocking: the password hash takes a deliberate ~0.1 s of CPU; call it from a worker thread.
        """
        account = self._verified(user, password, address)
        now = self._clock()
        session = WebSession(secrets.token_urlsafe(32), secrets.token_urlsafe(32), account, now, now, now)
        with self._lock:
            self._forget_expired(now)
            self._sessions[session.token] = session
        return session

    def second_operator(self, user: str, password: str, address: str, for_user: str) -> Account:
        """``user``'s account, approving at ``for_user``'s console what ``for_user`` does: their
        password checked as at sign-in (and throttled alike), an operator, not ``for_user``.
        SignInRefused says why not. Blocking, as :meth:`sign_in`."""
        if user == for_user:
            raise SignInRefused(403, f"{for_user} asks for this: a second operator must approve, not {for_user}")
        account = self._verified(user, password, address)
        if not account.may_act:
            raise SignInRefused(403, f"{user} is an {account.role.value}: only an operator approves commands")
        return account

    def _verified(self, user: str, password: str, address: str) -> Account:
        """The account whose password this is (throttled per user and address), or SignInRefused."""
        wait = self.throttle.wait(user, address)
        if wait > 0:
            seconds = math.ceil(wait)
            raise SignInRefused(429, f"too many failed sign-ins: try again in {seconds} s", retry_after=seconds)
        account = self.store.verify(user, password)
        if account is None:
            self.throttle.failed(user, address)
            raise SignInRefused(401, "wrong user id or password")
        self.throttle.succeeded(user, address)
        return account

    def sign_out(self, token: str) -> None:
        with self._lock:
            self._sessions.pop(token, None)

    def session(self, connection: HTTPConnection) -> WebSession:
        """The live session of a request or WebSocket (and marks it used); SignInRefused(401) says why not."""
        token = connection.cookies.get(COOKIE)
        if not token:
            raise SignInRefused(401, "sign in first")
        now = self._clock()
        with self._lock:
            session = self._sessions.get(token)
            ended = self._ended.get(token)
        if session is None:
            raise SignInRefused(401, ended or "sign in first (your session ended or the server restarted)")
        if now - session.created > self.limits.absolute:
            self._end(token, "your session reached its time limit: sign in again")
        if now - session.last_used > self.limits.idle:
            self._end(token, "your session expired after inactivity: sign in again")
        if now - session.checked > self.limits.recheck:
            current = self.store.get(session.account.user)
            if current is None or current.password_changed != session.account.password_changed:
                self._end(token, "your account or password changed: sign in again")
            else:
                session.account, session.checked = current, now  # a role change takes effect here
        session.last_used = now
        return session

    def notice(self, notice: ChangeNotice) -> None:
        """Change-feed subscriber: an account changed (or notices were missed): recheck its sessions
        at their next use."""
        if notice.channel not in ("accounts", "resync"):
            return
        with self._lock:
            for session in self._sessions.values():
                if notice.channel == "resync" or session.account.user == notice.payload:
                    session.checked = -math.inf

    def _end(self, token: str, message: str) -> None:
        with self._lock:
            self._sessions.pop(token, None)
            self._ended[token] = message
            while len(self._ended) > _ENDED_KEPT:
                self._ended.popitem(last=False)
        raise SignInRefused(401, message)

    def _forget_expired(self, now: float) -> None:
        """Drop sessions past a limit (called with the lock held, at each sign-in)."""
        for token in [
            t
            for t, s in self._sessions.items()
            if now - s.created > self.limits.absolute or now - s.last_used > self.limits.idle
        ]:
            del self._sessions[token]
