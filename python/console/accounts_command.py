"""``caretaker accounts``: add, change and remove the web view's accounts in the ground database.

Passwords come from a prompt (typed twice, not echoed) or, when stdin is not a terminal, from
its first line, so scripts pipe them in. Never from the command line: argv is visible to every
user of the machine (``ps``) and lands in shell histories. An agent has no password: ``token``
prints a new token of it once (:mod:`records.agent_tokens`), ``tokens`` lists them, ``revoke`` ends them.
"""

from __future__ import annotations

import argparse
import getpass
import sys
from datetime import UTC, datetime

from sqlalchemy.exc import OperationalError

from console.accounts import AccountsError, AccountStore, Role
from records.agent_tokens import TokenError, TokenStore, parse_duration
from records.audit_log import DEFAULT_DB

__all__ = ["main"]


class _PasswordError(Exception):
    """The password could not be read (prompts differ, nothing on stdin)."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="caretaker accounts",
        description="Manage who may sign in to the web view (caretaker serve). Passwords are read from a "
        "prompt, or from the first line of stdin when it is not a terminal; never from arguments.",
    )
    parser.add_argument(
        "--db", default=DEFAULT_DB, help=f"the ground database, as for caretaker serve (default: {DEFAULT_DB})"
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add = commands.add_parser("add", help="create an account (asks for its password; an agent has none)")
    add.add_argument("user")
    add.add_argument("--role", required=True, choices=[r.value for r in Role])
    add.add_argument("--name", default="", help="the person's name as the page shows it")
    commands.add_parser("set-password", help="replace a password (the user's sessions end)").add_argument("user")
    role = commands.add_parser("set-role", help="make a user an operator, an observer or an agent")
    role.add_argument("user")
    role.add_argument("role", choices=[r.value for r in Role])
    commands.add_parser("remove", help="delete an account (its sessions end)").add_argument("user")
    commands.add_parser("list", help="every account with its role")
    token = commands.add_parser("token", help="print a new token of an agent, once (only its hash is kept)")
    token.add_argument("user")
    token.add_argument("--expires-in", metavar="DURATION", help="e.g. 7d, 12h, 30m (default: until revoked)")
    commands.add_parser("tokens", help="an agent's tokens: number, issued, valid, expired or revoked").add_argument(
        "user"
    )
    revoke = commands.add_parser("revoke", help="revoke an agent's token (NUMBER) or all of its tokens")
    revoke.add_argument("user")
    revoke.add_argument("number", nargs="?", type=int, help="the token's number (see tokens); default: all")
    return parser


def _password(user: str) -> str:
    if not sys.stdin.isatty():
        line = sys.stdin.readline()
        if not line:
            raise _PasswordError("no password on stdin (give it as the first line)")
        return line.rstrip("\r\n")
    first = getpass.getpass(f"password for {user}: ")
    if getpass.getpass("again: ") != first:
        raise _PasswordError("the two passwords differ; nothing changed")
    return first


def _tokens(tokens: TokenStore, args: argparse.Namespace) -> None:
    if args.command == "token":
        issued = tokens.issue(args.user, parse_duration(args.expires_in) if args.expires_in else None)
        until = f"until {issued.expires:%Y-%m-%d %H:%M}Z" if issued.expires else "until revoked"
        print(f"token {issued.token_id} of {issued.user}, valid {until} (shown once, keep it secret):", file=sys.stderr)
        print(issued.token)
    elif args.command == "tokens":
        now = datetime.now(UTC)
        for info in tokens.tokens(args.user):
            print(f"{info.token_id}\tissued {info.created:%Y-%m-%d %H:%M}Z\t{info.state(now)}")
    else:
        revoked = tokens.revoke(args.user, args.number)
        which = f"token {args.number}" if args.number is not None else "tokens"
        print(f"revoked {revoked} {which} of {args.user}" if revoked else f"{args.user} had no valid {which} to revoke")


def main(argv: list[str] | None = None) -> int:
    """Run one accounts command; returns the exit code (2 with a message on any refusal)."""
    args = _parser().parse_args(argv)
    store: AccountStore | None = None
    try:
        store = AccountStore(args.db)  # its schema check writes too
        if args.command == "add":
            password = None if args.role == Role.AGENT.value else _password(args.user)
            account = store.add(args.user, args.role, password, name=args.name)
            print(f"added {account.user} ({account.role.value})")
        elif args.command == "set-password":
            if store.get(args.user) is None:  # before asking for a password that would be thrown away
                raise AccountsError(f"no account {args.user!r} (see `caretaker accounts list`)")
            store.set_password(args.user, _password(args.user))
            print(f"password of {args.user} changed")
        elif args.command == "set-role":
            store.set_role(args.user, args.role)
            print(f"{args.user} is now an {args.role}")
        elif args.command == "remove":
            store.remove(args.user)
            print(f"removed {args.user}")
        elif args.command in ("token", "tokens", "revoke"):
            _tokens(TokenStore(store.engine), args)
        else:
            for account in store.accounts():
                print(f"{account.user}\t{account.role.value}\t{account.name}")
    except (AccountsError, TokenError, _PasswordError) as exc:
        print(f"caretaker accounts: {exc}", file=sys.stderr)
        return 2
    except OperationalError as exc:  # a transaction rolls back whole: nothing half-changed
        print(
            f"caretaker accounts: the database did not take the change ({exc.orig}); nothing changed, try again",
            file=sys.stderr,
        )
        return 2
    except KeyboardInterrupt:
        print("caretaker accounts: interrupted; nothing changed", file=sys.stderr)
        return 2
    finally:
        if store is not None:
            store.close()
    return 0
