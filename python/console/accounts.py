"""Who may use the web view: accounts in the ground database, passwords hashed with argon2id.

Accounts live in the same database as the audit log (``--db``), so every console of a ground
segment signs people in against one list, and ``caretaker accounts`` (:mod:`console.accounts_command`)
manages it. An *operator* may act on runs (start, send, record, skip, ...); an *observer* may
only watch. The server checks the role on every action, so hiding buttons in the page is a
convenience, never the protection. An *agent* is an assistant program, not a person: it has no
password and never signs in to the console; it reaches the ground through ``caretaker agent``
with a token (:mod:`records.agent_tokens`), and may read, propose runs and ask for a halt, nothing more.

Passwords are never stored: only their argon2id hash (argon2-cffi's defaults, re-hashed at the
next sign-in when those defaults grow, where the console's role may write the table). The table
``console_accounts(user_id PK, name, role, password_hash, created, password_changed)`` belongs to
the ground database's schema (revision 0004 of :mod:`records.migrations`): on PostgreSQL the
consoles' role only reads it and ``caretaker accounts``, run as the database owner, changes it. A
change NOTIFYs every console (:mod:`ground.change_feed`), which ends that user's sessions.
"""

from __future__ import annotations

import enum
import functools
import logging
import re
from dataclasses import dataclass
from datetime import UTC, datetime

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError, VerifyMismatchError
from sqlalchemy import select, update
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.exc import DBAPIError
from sqlalchemy.orm import DeclarativeBase, Mapped, Session

from records.audit_log import database_url, open_engine
from records.audit_schema import ensure_schema
from records.console_tables import console_accounts

__all__ = ["Account", "AccountStore", "AccountsError", "Role", "TABLE"]

log = logging.getLogger(__name__)

_USER_ID = re.compile(r"^[A-Za-z0-9_.@-]{1,64}$")
#: NIST SP 800-63B's floor for a chosen secret; the ceiling keeps hashing bounded.
MIN_PASSWORD = 8
MAX_PASSWORD = 1024
#: The table's name in the ground database.
TABLE = console_accounts.name
#: The password hash of an agent: no hash at all, so no password ever verifies against it.
NO_PASSWORD = "!agent: authenticates with tokens, never a password"


class Role(str, enum.Enum):
    """What a signed-in person may do."""

    OPERATOR = "operator"
    """May start runs and act on them; every action is logged with the user id."""
    OBSERVER = "observer"
    """May watch runs, their telemetry, camera and audit log; never act."""
    AGENT = "agent"
    """An assistant program (``caretaker agent``, with a token): reads, proposes runs, asks for a halt."""


class AccountsError(ValueError):
    """An account operation cannot be done; the message names the user and what to fix."""


@dataclass(frozen=True)
class Account:
    """One person who may sign in. ``password_changed`` lets sessions end when the password changes."""

    user: str
    role: Role
    name: str = ""
    password_changed: datetime | None = None

    @property
    def may_act(self) -> bool:
        return self.role is Role.OPERATOR

    @property
    def may_halt(self) -> bool:
        """A halt is the safe direction: an agent may ask for one, as an operator may."""
        return self.role in (Role.OPERATOR, Role.AGENT)


class _Base(DeclarativeBase):
    pass


class _AccountRow(_Base):
    __table__ = console_accounts  # the columns are defined once, in records.console_tables

    user_id: Mapped[str]
    name: Mapped[str]
    role: Mapped[str]
    password_hash: Mapped[str]
    created: Mapped[datetime]
    password_changed: Mapped[datetime]

    def account(self) -> Account:
        changed = self.password_changed if self.password_changed.tzinfo else self.password_changed.replace(tzinfo=UTC)
        return Account(self.user_id, Role(self.role), self.name, changed)


def check_user_id(user: str) -> str:
    """``user`` if it is a valid user id; AccountsError says what one looks like."""
    if not _USER_ID.match(user):
        raise AccountsError(f"user id {user!r}: use 1-64 letters, digits or _.@-")
    return user


def check_role(role: str) -> Role:
    try:
        return Role(role)
    except ValueError:
        raise AccountsError(f"role {role!r}: must be one of {', '.join(r.value for r in Role)}") from None


def check_password(password: str) -> str:
    if len(password) < MIN_PASSWORD:
        raise AccountsError(f"the password is too short: use at least {MIN_PASSWORD} characters")
    if len(password) > MAX_PASSWORD:
        raise AccountsError(f"the password is too long: at most {MAX_PASSWORD} characters")
    return password


class AccountStore:
    """The accounts table of one database. Thread-safe: one session per call."""

    def __init__(self, url: str) -> None:
        """Open the accounts of the ground database at ``url``, bringing its schema up to date where
        this role may (AuditSchemaError says what to do where it may not)."""
        self.url = url
        self._engine: Engine = open_engine(url)
        try:
            ensure_schema(self._engine, make_url(database_url(url)).render_as_string(hide_password=True))
        except BaseException:
            self._engine.dispose()
            raise
        # A change reads its row, then writes: begun deferred, SQLite refuses the write at once
        # ("database is locked", no busy wait) when a console wrote since the read began. On
        # SQLite each change takes the write lock first and waits its turn; PostgreSQL ignores it.
        self._changes = self._engine.execution_options(sqlite_begin="BEGIN IMMEDIATE")
        self._hasher = PasswordHasher()

    @functools.cached_property
    def _decoy(self) -> str:
        """Verified against when the user id is unknown, so a wrong user id costs as much time as a wrong
        password. Made at the first such sign-in, not at every opening: a hash costs as much as a check,
        and a supervisor opens the accounts for each run it follows."""
        return self._hasher.hash("not a password of anyone")

    @property
    def engine(self) -> Engine:
        """The ground database's engine (the agents' tokens live beside the accounts)."""
        return self._engine

    def add(self, user: str, role: str, password: str | None, *, name: str = "") -> Account:
        """Create an account; AccountsError when the user id is taken or a value is invalid. An agent
        has no password (``None``); everyone else must have one."""
        checked_role = check_role(role)
        if (checked_role is Role.AGENT) != (password is None):
            raise AccountsError(
                "an agent has no password: it authenticates with tokens (caretaker accounts token)"
                if password is not None
                else f"an {checked_role.value} needs a password"
            )
        row = _AccountRow(
            user_id=check_user_id(user),
            name=name,
            role=checked_role.value,
            password_hash=NO_PASSWORD if password is None else self._hasher.hash(check_password(password)),
            created=_now(),
            password_changed=_now(),
        )
        account = row.account()
        with Session(self._changes) as session, session.begin():
            if session.get(_AccountRow, user) is not None:
                raise AccountsError(f"user {user!r} already has an account: use set-password, set-role or remove")
            session.add(row)
        return account

    def set_password(self, user: str, password: str) -> None:
        """Replace a password; the user's sessions end (their stamp changes). An agent has none."""
        digest = self._hasher.hash(check_password(password))
        with Session(self._changes) as session, session.begin():
            row = self._row(session, user)
            if row.role == Role.AGENT.value:
                raise AccountsError(f"{user} is an agent: it has no password, only tokens (caretaker accounts token)")
            row.password_hash, row.password_changed = digest, _now()

    def set_role(self, user: str, role: str) -> None:
        """Change a role. Made an agent, the account loses its password (its sessions end); an agent
        made a person needs a password set before it can sign in."""
        checked = check_role(role)
        with Session(self._changes) as session, session.begin():
            row = self._row(session, user)
            row.role = checked.value
            if checked is Role.AGENT and row.password_hash != NO_PASSWORD:
                row.password_hash, row.password_changed = NO_PASSWORD, _now()

    def remove(self, user: str) -> None:
        with Session(self._changes) as session, session.begin():
            session.delete(self._row(session, user))

    def get(self, user: str) -> Account | None:
        with Session(self._engine) as session:
            row = session.get(_AccountRow, user)
            return row.account() if row is not None else None

    def accounts(self) -> list[Account]:
        """Every account, by user id."""
        with Session(self._engine) as session:
            return [row.account() for row in session.scalars(select(_AccountRow).order_by(_AccountRow.user_id))]

    def verify(self, user: str, password: str) -> Account | None:
        """The account when ``password`` is its password, else None (same cost for unknown users)."""
        password = password[: MAX_PASSWORD + 1]  # longer never matches a stored one; this bounds the hashing
        with Session(self._engine) as session:
            row = session.get(_AccountRow, user) if _USER_ID.match(user) else None
            if row is None or row.role == Role.AGENT.value:  # an agent never signs in to the console
                _matches(self._hasher, self._decoy, password)
                return None
            if not _matches(self._hasher, row.password_hash, password):
                return None
            account, digest = row.account(), row.password_hash
        if self._hasher.check_needs_rehash(digest):
            self._rehash(user, digest, password)
        return account

    def _rehash(self, user: str, digest: str, password: str) -> None:
        """Store the password's hash with today's parameters (same password: the stamp, and so the
        sessions, stay). A console whose role may only read accounts leaves that to the owner."""
        try:
            with self._engine.begin() as connection:
                connection.execute(
                    update(_AccountRow)
                    .where(_AccountRow.user_id == user, _AccountRow.password_hash == digest)
                    .values(password_hash=self._hasher.hash(password))
                )
        except DBAPIError as exc:
            if getattr(exc.orig, "sqlstate", None) != "42501":  # insufficient_privilege: a read-only console
                raise
            log.info("the hash of %s's password uses old parameters; this console may not update it", user)

    def _row(self, session: Session, user: str) -> _AccountRow:
        row = session.get(_AccountRow, user)
        if row is None:
            raise AccountsError(f"no account {user!r} (see `caretaker accounts list`)")
        return row

    def close(self) -> None:
        self._engine.dispose()


def _matches(hasher: PasswordHasher, digest: str, password: str) -> bool:
    try:
        return hasher.verify(digest, password)
    except (VerifyMismatchError, VerificationError, InvalidHashError):
        return False


def _now() -> datetime:
    return datetime.now(UTC)
