"""Who may use the web view, and what they may do: accounts from a YAML file.

The file is a deployment's config (``caretaker serve --accounts FILE``); the example shipped
next to this module is ``accounts.example.yaml``. An *operator* may act on runs (start, send,
record, skip, ...); an *observer* may only watch. The server checks the role on every action,
so hiding buttons in the page is a convenience, never the protection.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass
from pathlib import Path

import yaml

__all__ = ["Account", "AccountsError", "Role", "load_accounts"]

_USER_ID = re.compile(r"^[A-Za-z0-9_.@-]{1,64}$")

#: The accounts file used when ``--accounts`` is not given.
EXAMPLE_ACCOUNTS = Path(__file__).with_name("accounts.example.yaml")


class Role(str, enum.Enum):
    """What a signed-in person may do."""

    OPERATOR = "operator"
    """May start runs and act on them; every action is logged with the user id."""
    OBSERVER = "observer"
    """May watch runs, their telemetry, camera and audit log; never act."""


class AccountsError(ValueError):
    """The accounts file is malformed; the message names the file, entry and what to fix."""


@dataclass(frozen=True)
class Account:
    """One person who may sign in."""

    user: str
    role: Role
    name: str = ""

    @property
    def may_act(self) -> bool:
        return self.role is Role.OPERATOR


def load_accounts(path: str | Path) -> dict[str, Account]:
    """The accounts of a file, keyed by user id; AccountsError says what is wrong and where."""
    path = Path(path)
    try:
        document = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise AccountsError(f"{path}: cannot read the accounts file: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise AccountsError(f"{path}: not valid YAML: {exc}") from exc
    entries = document.get("accounts") if isinstance(document, dict) else None
    if not isinstance(entries, list) or not entries:
        raise AccountsError(f"{path}: expected a top-level 'accounts:' list with at least one entry")
    accounts: dict[str, Account] = {}
    for index, entry in enumerate(entries, start=1):
        where = f"{path}: accounts entry {index}"
        if not isinstance(entry, dict):
            raise AccountsError(f"{where}: expected a mapping with 'user' and 'role'")
        unknown = set(entry) - {"user", "role", "name"}
        if unknown:
            raise AccountsError(f"{where}: unknown key(s) {', '.join(sorted(unknown))} (allowed: user, role, name)")
        user = str(entry.get("user", ""))
        if not _USER_ID.match(user):
            raise AccountsError(f"{where}: 'user' must be 1-64 letters, digits or _.@- (got {user!r})")
        try:
            role = Role(str(entry.get("role", "")))
        except ValueError:
            roles = ", ".join(r.value for r in Role)
            raise AccountsError(f"{where} ({user}): 'role' must be one of {roles} (got {entry.get('role')!r})") from None
        if user in accounts:
            raise AccountsError(f"{where}: user {user!r} is listed twice")
        accounts[user] = Account(user, role, str(entry.get("name", "")))
    return accounts
