"""The tokens an agent authenticates with: printed once, stored only as their hash, expiring, revocable.

``caretaker accounts token NAME [--expires-in 7d]`` issues one for an account of role ``agent``
(:class:`console.accounts.Role`; read here from the accounts table, this store being below the
console). The token is 32 random bytes (``ctk_`` and URL-safe base64);
the table ``agent_tokens`` (:mod:`records.agent_tables`) keeps its SHA-256, who it belongs to,
when it expires and whether it was revoked. A fast hash suffices where a password needs argon2:
a token is never chosen by a person, so no guess can be tried against its hash.

:meth:`TokenStore.authenticate` is the one check ``caretaker agent`` makes, at start-up (stdio)
and on every request (HTTP): the token is known, not revoked, not expired, and its account still
exists and is still an agent (a role changed or an account removed ends its tokens). A refusal
names its rule (:class:`TokenRefused`).
"""

from __future__ import annotations

import hashlib
import re
import secrets
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from sqlalchemy import insert, select, update
from sqlalchemy.engine import Engine

from records.agent_tables import agent_tokens
from records.audit_chain import utc
from records.console_tables import console_accounts
from records.refusals import Refused

__all__ = ["AGENT_ROLE", "TOKEN_PREFIX", "IssuedToken", "TokenError", "TokenInfo", "TokenRefused", "TokenStore"]

#: The role of an agent's account (``console.accounts.Role.AGENT``).
AGENT_ROLE = "agent"

#: What every token starts with, so one pasted in the wrong place is recognisable (and greppable).
TOKEN_PREFIX = "ctk_"
_T = agent_tokens.c
_DURATION = re.compile(r"^(\d+)([smhd])$")
_UNITS = {"s": 1, "m": 60, "h": 3600, "d": 86400}


class TokenError(ValueError):
    """A token cannot be issued or revoked as asked; the message says what to fix."""


class TokenRefused(Refused):
    """A token that does not authenticate an agent; ``rule`` names why (as a refusal is recorded)."""


@dataclass(frozen=True)
class IssuedToken:
    """A new token: ``token`` is shown once and never stored."""

    token_id: int
    user: str
    token: str
    expires: datetime | None


@dataclass(frozen=True)
class TokenInfo:
    """A stored token as ``caretaker accounts tokens`` lists it (never the token itself)."""

    token_id: int
    user: str
    created: datetime
    expires: datetime | None
    revoked: datetime | None

    def state(self, now: datetime) -> str:
        if self.revoked is not None:
            return f"revoked {self.revoked:%Y-%m-%d %H:%M}Z"
        if self.expires is not None and self.expires <= now:
            return f"expired {self.expires:%Y-%m-%d %H:%M}Z"
        return "valid" + (f" until {self.expires:%Y-%m-%d %H:%M}Z" if self.expires else " until revoked")


def parse_duration(text: str) -> timedelta:
    """``7d``, ``12h``, ``30m``, ``90s`` as a duration; TokenError says what one looks like."""
    match = _DURATION.match(text.strip())
    if match is None or int(match.group(1)) == 0:
        raise TokenError(f"duration {text!r}: write a positive number and a unit, e.g. 7d, 12h, 30m or 90s")
    return timedelta(seconds=int(match.group(1)) * _UNITS[match.group(2)])


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


class TokenStore:
    """The ``agent_tokens`` table of one ground database, with the accounts they belong to."""

    def __init__(self, engine: Engine) -> None:
        self._engine = engine

    def role(self, user: str) -> str | None:
        """``user``'s role, None when there is no such account."""
        with self._engine.connect() as connection:
            role = connection.scalar(select(console_accounts.c.role).where(console_accounts.c.user_id == user))
        return None if role is None else str(role)

    def issue(self, user: str, expires_in: timedelta | None = None) -> IssuedToken:
        """A new token for the agent ``user``; TokenError when ``user`` is no agent."""
        role = self.role(user)
        if role is None:
            raise TokenError(f"no account {user!r} (see `caretaker accounts list`)")
        if role != AGENT_ROLE:
            raise TokenError(f"{user} is an {role}: only an agent has tokens")
        token = TOKEN_PREFIX + secrets.token_urlsafe(32)
        now = datetime.now(UTC)
        expires = now + expires_in if expires_in is not None else None
        with self._engine.begin() as connection:
            token_id = connection.execute(
                insert(agent_tokens)
                .values(user_id=user, token_sha256=token_hash(token), created=now, expires=expires)
                .returning(_T.id)
            ).scalar_one()
        return IssuedToken(int(token_id), user, token, expires)

    def tokens(self, user: str) -> list[TokenInfo]:
        """Every token ``user`` was given, oldest first."""
        with self._engine.connect() as connection:
            rows = connection.execute(select(agent_tokens).where(_T.user_id == user).order_by(_T.id)).all()
        return [TokenInfo(row.id, row.user_id, utc(row.created), _utc(row.expires), _utc(row.revoked)) for row in rows]

    def revoke(self, user: str, token_id: int | None = None) -> int:
        """Revoke one of ``user``'s tokens (``token_id``) or all of them; how many were still unrevoked.
        TokenError when ``token_id`` is not one of ``user``'s."""
        query = update(agent_tokens).where(_T.user_id == user, _T.revoked.is_(None))
        if token_id is not None:
            if all(info.token_id != token_id for info in self.tokens(user)):
                raise TokenError(f"{user} has no token {token_id} (see `caretaker accounts tokens {user}`)")
            query = query.where(_T.id == token_id)
        with self._engine.begin() as connection:
            return int(connection.execute(query.values(revoked=datetime.now(UTC))).rowcount)

    def authenticate(self, token: str, *, agent: str | None = None) -> str:
        """The agent (its user id) whose valid token this is (of ``agent``, when given); TokenRefused says why not."""
        if not token:
            raise TokenRefused("agent_token", "no token: give the agent's (CARETAKER_AGENT_TOKEN, or a bearer token)")
        with self._engine.connect() as connection:
            row = connection.execute(
                select(_T.user_id, _T.expires, _T.revoked).where(_T.token_sha256 == token_hash(token[:200]))
            ).first()
        if row is None:
            raise TokenRefused("agent_token", "unknown token: it was never issued here")
        if agent is not None and row.user_id != agent:
            raise TokenRefused("agent_token", f"this token belongs to another account, not to {agent}")
        if row.revoked is not None:
            revoked = utc(row.revoked)
            raise TokenRefused("agent_token", f"the token of {row.user_id} was revoked at {revoked:%Y-%m-%d %H:%M:%S}Z")
        expires = _utc(row.expires)
        if expires is not None and expires <= datetime.now(UTC):
            raise TokenRefused("agent_token", f"the token of {row.user_id} expired at {expires:%Y-%m-%d %H:%M:%S}Z")
        role = self.role(row.user_id)
        if role is None:
            raise TokenRefused("agent_token", f"the account {row.user_id} no longer exists")
        if role != AGENT_ROLE:
            raise TokenRefused("agent_role", f"{row.user_id} is an {role} now, not an agent")
        return str(row.user_id)


def _utc(moment: datetime | None) -> datetime | None:
    return None if moment is None else utc(moment)
