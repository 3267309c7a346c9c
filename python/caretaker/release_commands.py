"""``caretaker release`` and ``caretaker releases list``: releases from the command line.

Why: a team that keeps its procedures in version control releases them from its pipeline, not
only on the Author page. The rules and the rows are the Author page's
(:meth:`records.releases.ReleaseStore.release_by_two`): the author (``--user``) asks for the
release of the file's version and a second operator (``--approver``), neither its author nor who
saved it on the Author page, releases it; both are operators of the ground database, each
proving it with their password. Passwords come from the environment, a prompt, or stdin, never
from the command line (argv is visible to every user of the machine and lands in shell
histories).

Exit codes: 0 released (or listed); 1 the procedure has errors; 2 refused (the message says why
and what to do), a bad command line or an unusable database.
"""

from __future__ import annotations

import argparse
import getpass
import logging
import os
import sys
from datetime import UTC
from pathlib import Path

from sqlalchemy.exc import SQLAlchemyError

from caretaker.command_options import load_sysreps
from pride.approvals import APPROVER_PASSWORD_ENV
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRepError
from records.audit_log import DEFAULT_DB, AuditLog, AuditLogUnavailable
from records.audit_schema import AuditSchemaError
from records.releases import Release, ReleaseRefused, ReleaseStore, procedure_digest, short

__all__ = ["USER_PASSWORD_ENV", "release_main", "releases_main"]

#: The author's (``--user``'s) password; the approver's is in :data:`pride.approvals.APPROVER_PASSWORD_ENV`.
USER_PASSWORD_ENV = "CARETAKER_PASSWORD"


def _db_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--db",
        default=os.environ.get("CARETAKER_DB", DEFAULT_DB),
        metavar="URL",
        help=f"the ground database (default $CARETAKER_DB, else {DEFAULT_DB}), as for caretaker run and serve",
    )


def release_main(argv: list[str] | None = None) -> int:
    """``caretaker release PROC.xml --user AUTHOR --approver SECOND``."""
    parser = argparse.ArgumentParser(
        prog="caretaker release",
        description="Release a procedure file's version: its author asks, a second operator releases it. "
        f"Passwords: the author's from ${USER_PASSWORD_ENV}, the approver's from ${APPROVER_PASSWORD_ENV}; "
        "either one missing is asked at the terminal, or read from stdin (one line each, the author's first).",
    )
    parser.add_argument("procedure", metavar="PROC", help="the procedure XML file (its sub-procedures go with it)")
    parser.add_argument("--user", required=True, metavar="AUTHOR", help="who asks for the release (its author)")
    parser.add_argument(
        "--approver",
        required=True,
        metavar="USER",
        help="the second operator who reviewed this version and releases it: not its author, not who saved it "
        "on the Author page",
    )
    _db_option(parser)
    parser.add_argument(
        "--sysrep-dir",
        action="append",
        metavar="DIR",
        help="folder of SysRep YAML files the procedure is checked against (repeatable; default: sysrep/)",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    path = Path(args.procedure)
    try:
        content = path.read_text(encoding="utf-8")
        checked = check_procedure(path, load_sysreps(args.sysrep_dir))
        sha = procedure_digest(checked)
        if path.read_text(encoding="utf-8") != content:
            raise ReleaseRefused(f"{args.procedure} changed while it was being read: release it once it is written")
    except (OSError, UnicodeDecodeError, SysRepError) as exc:
        print(f"caretaker release: {args.procedure}: cannot be read: {exc}", file=sys.stderr)
        return 2
    except ProcedureError as exc:
        for problem in exc.problems:
            print(problem, file=sys.stderr)
        print(f"caretaker release: {args.procedure} has errors; it is not released", file=sys.stderr)
        return 1
    except ReleaseRefused as exc:
        print(f"caretaker release: {exc}", file=sys.stderr)
        return 2
    audit = _open(args.db, "release")
    if audit is None:
        return 2
    try:
        author = _operator(audit, args.user, _password(args.user, USER_PASSWORD_ENV, "asking for the release"))
        approver = _operator(audit, args.approver, _password(args.approver, APPROVER_PASSWORD_ENV, "releasing"))
        release = ReleaseStore(audit.engine).release_by_two(
            checked.procedure.id, sha, author, approver, args.procedure, content
        )
    except (ValueError, AuditSchemaError) as exc:  # ReleaseRefused among them
        print(f"caretaker release: {exc}", file=sys.stderr)
        return 2
    except SQLAlchemyError as exc:  # one transaction: nothing half-written
        print(
            f"caretaker release: {audit.location} did not take the release ({_first_line(exc)}); nothing changed",
            file=sys.stderr,
        )
        return 2
    finally:
        audit.close()
    print(
        f"RELEASED {args.procedure}: {release.procedure} release {release.number} (sha256 {short(release.sha256)}), "
        f"asked by {release.requested_by}, released by {release.released_by}"
    )
    return 0


def _password(user: str, variable: str, doing: str) -> str:
    """``user``'s password: from ``$variable``, else asked at the terminal, else the next line of stdin."""
    password = os.environ.get(variable)
    if password:
        return password
    if sys.stdin.isatty():
        return getpass.getpass(f"{user}'s password ({doing}): ")
    line = sys.stdin.readline()
    if not line.strip("\r\n"):
        raise ValueError(f"{user}: no password (give it in ${variable}, or as a line of stdin)")
    return line.rstrip("\r\n")


def _open(db: str, command: str) -> AuditLog | None:
    """The ground database at ``db``, its schema brought up to date where this role may (None: it
    cannot be used; the reason is printed)."""
    try:
        return AuditLog(db)
    except (AuditSchemaError, AuditLogUnavailable) as exc:
        print(f"caretaker {command}: {exc}", file=sys.stderr)
    except SQLAlchemyError as exc:  # a URL no driver takes, a file that cannot be opened
        print(f"caretaker {command}: the ground database cannot be opened: {_first_line(exc)}", file=sys.stderr)
    return None


def _first_line(exc: Exception) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _operator(audit: AuditLog, user: str, password: str) -> str:
    """The user id of an operator whose password checks out in the ground database (ValueError: why not)."""
    from console.accounts import AccountStore  # the web stack's accounts, loaded only here

    store = AccountStore(audit.url)
    try:
        account = store.verify(user, password)
    finally:
        store.close()
    if account is None:
        raise ValueError(f"{user}: unknown user or wrong password (accounts of {audit.location})")
    if not account.may_act:
        raise ValueError(f"{user} is an {account.role.value}: only operators ask for and give releases")
    return account.user


def releases_main(argv: list[str] | None = None) -> int:
    """``caretaker releases list``: every release, oldest first."""
    parser = argparse.ArgumentParser(prog="caretaker releases", description="what is released in the ground database")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    listing = commands.add_parser(
        "list",
        help="every release, oldest first: procedure, release, sha256, author, approver, when, file",
    )
    listing.add_argument("--procedure", metavar="ID", help="only the releases of the procedure with this id")
    _db_option(listing)
    args = parser.parse_args(argv)
    audit = _open(args.db, "releases")
    if audit is None:
        return 2
    try:
        releases = [r for r in ReleaseStore(audit.engine).releases() if args.procedure in (None, r.procedure)]
    except SQLAlchemyError as exc:
        print(f"caretaker releases: {audit.location} cannot be read: {_first_line(exc)}", file=sys.stderr)
        return 2
    finally:
        audit.close()
    print("\t".join(("procedure", "release", "sha256", "author", "approver", "released", "file")))
    for release in releases:
        print(_line(release))
    return 0


def _line(release: Release) -> str:
    at = release.at if release.at.tzinfo else release.at.replace(tzinfo=UTC)  # SQLite gives back naive UTC
    when = at.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    fields = (release.procedure, str(release.number), release.sha256, release.requested_by, release.released_by)
    return "\t".join((*fields, when, release.path))
