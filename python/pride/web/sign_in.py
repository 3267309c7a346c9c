"""Signed-in browsers: a random token in an HttpOnly cookie, mapped to an account.

People sign in with a user id listed in the accounts file (no passwords: the server binds to
loopback and the accounts file says who may act). Tokens live in memory: restarting the server
signs everyone out, which is what a restarted ground station should do.
"""

from __future__ import annotations

import secrets
import threading

from starlette.requests import HTTPConnection

from pride.web.accounts import Account

__all__ = ["COOKIE", "SignIns"]

COOKIE = "caretaker_session"


class SignIns:
    """Tokens of signed-in browsers."""

    def __init__(self, accounts: dict[str, Account]) -> None:
        self.accounts = accounts
        self._lock = threading.Lock()  # guards _tokens
        self._tokens: dict[str, str] = {}

    def sign_in(self, user: str) -> tuple[str, Account] | None:
        """A new token for ``user``, or None when the accounts file does not list them."""
        account = self.accounts.get(user)
        if account is None:
            return None
        token = secrets.token_urlsafe(24)
        with self._lock:
            self._tokens[token] = user
        return token, account

    def sign_out(self, token: str) -> None:
        with self._lock:
            self._tokens.pop(token, None)

    def account_of(self, connection: HTTPConnection) -> Account | None:
        """The account of a request or WebSocket, from its cookie."""
        token = connection.cookies.get(COOKIE)
        if not token:
            return None
        with self._lock:
            user = self._tokens.get(token)
        return self.accounts.get(user) if user else None
