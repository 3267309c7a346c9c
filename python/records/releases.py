"""Released procedures: operators run a version a second operator reviewed; a draft only rehearses.

Why: an edited procedure file should not reach a robot before someone other than its author has
read it (as Epsilon3's released procedure versions). So a version is identified by its content
hash (:func:`procedure_digest`: the file and every sub-procedure it calls), and the ground database
keeps, per procedure id, an append-only history in ``procedure_releases``: who saved a version on
the Author page, who asked for a version's release, and who released it (with its text and a
release number, 1, 2, ...). Releasing needs a request, by someone else than the releaser; nobody
releases a version they saved or asked for themselves. The Author page asks and releases in two
acts by two signed-in operators; ``caretaker release`` (:meth:`ReleaseStore.release_by_two`) in
one act by two authenticated operators, under the same rules and with the same rows.

A run records the version it ran (:class:`RunVersion`, in its ``run_started``): the release, or
that it is a *rehearsal*. :func:`version_for_run` says whether a run may start: a released version
may; a draft (never released) or a file changed since its release is refused with the reason,
unless the run is a rehearsal, which only a robot side flagged as a simulator takes
(:mod:`pride.robot_sides`).
"""

from __future__ import annotations

import hashlib
import logging
import os
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import Column, DateTime, Integer, MetaData, String, Table, Text, insert, select
from sqlalchemy.engine import Engine

from pride.event_payloads import Payload, RunStarted
from pride.robot_sides import RobotSide
from pride.run_version import RunVersion
from procedure_language.lint import CheckedProcedure

__all__ = [
    "Release",
    "ReleaseRefused",
    "ReleaseStore",
    "VersionState",
    "procedure_digest",
    "procedure_releases",
    "resume_refusal",
    "short",
    "version_for_run",
]

log = logging.getLogger(__name__)

_metadata = MetaData()
#: The history of versions (revision 0005 of :mod:`records.migrations`); rows are only ever added.
procedure_releases = Table(
    "procedure_releases",
    _metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("procedure", String(120), nullable=False, index=True),
    Column("kind", String(16), nullable=False),  # saved, requested, released
    Column("sha256", String(64), nullable=False),
    Column("user_id", String(64), nullable=False),
    Column("at", DateTime(timezone=True), nullable=False),
    Column("release", Integer, nullable=True),  # released rows: 1, 2, ... per procedure
    Column("path", Text, nullable=False),  # the file as the actor named it
    Column("content", Text, nullable=True),  # released rows: the procedure's text
)


class ReleaseRefused(ValueError):
    """A release or a run refused; the message says why and what to do."""


def procedure_digest(checked: CheckedProcedure) -> str:
    """The sha256 of a procedure version: its file and every sub-procedure it calls, each named by
    its path relative to the procedure's folder (so moving the folder keeps the version)."""
    main = Path(checked.procedure.path).resolve()
    files = [main, *sorted(Path(p).resolve() for p in checked.callees)]
    digest = hashlib.sha256()
    for path in files:
        name = path.name if path == main else os.path.relpath(path, main.parent)
        digest.update(name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def short(sha: str) -> str:
    """A hash as people compare it: its first 8 digits."""
    return sha[:8] + "…"


@dataclass(frozen=True)
class Release:
    """A released version of a procedure."""

    procedure: str
    number: int
    sha256: str
    released_by: str
    at: datetime
    requested_by: str
    path: str  # the file as the releaser named it


@dataclass(frozen=True)
class VersionState:
    """Where a procedure's current file stands: its hash, its newest release, an open request."""

    sha256: str
    release: Release | None  # the newest release (of this or an older version)
    requested_by: str | None  # who asked for this version's release (None: nobody yet)
    saved_by: str | None  # who saved this version on the Author page (None: not saved there)

    @property
    def released(self) -> bool:
        return self.release is not None and self.release.sha256 == self.sha256

    def to_json(self) -> dict[str, Any]:
        release = self.release
        return {
            "sha256": self.sha256,
            "released": self.released,
            "release": None
            if release is None
            else {
                "number": release.number,
                "sha256": release.sha256,
                "released_by": release.released_by,
                "requested_by": release.requested_by,
                "at": release.at.isoformat(),
            },
            "requested_by": self.requested_by,
            "saved_by": self.saved_by,
        }


class ReleaseStore:
    """The ``procedure_releases`` history in the ground database."""

    def __init__(self, engine: Engine) -> None:
        self._engine = engine

    def state(self, procedure: str, sha256: str) -> VersionState:
        releases, requested, saved = self._history(procedure)
        version = (procedure, sha256)
        return VersionState(sha256, releases[-1] if releases else None, requested.get(version), saved.get(version))

    def releases(self) -> list[Release]:
        """Every release of every procedure, in the order they were given."""
        return self._history(None)[0]

    def _history(
        self, procedure: str | None
    ) -> tuple[list[Release], dict[tuple[str, str], str], dict[tuple[str, str], str]]:
        """The releases of ``procedure`` (None: of every one) oldest first, and who asked for and who
        saved each version, by (procedure, sha256); a release closes the request it answered."""
        query = select(procedure_releases).order_by(procedure_releases.c.id)
        if procedure is not None:
            query = query.where(procedure_releases.c.procedure == procedure)
        with self._engine.connect() as connection:
            rows = connection.execute(query).all()
        releases: list[Release] = []
        requested: dict[tuple[str, str], str] = {}
        saved: dict[tuple[str, str], str] = {}
        for row in rows:
            version = (row.procedure, row.sha256)
            if row.kind == "released":
                asked = requested.pop(version, "")
                releases.append(Release(row.procedure, row.release, row.sha256, row.user_id, row.at, asked, row.path))
            elif row.kind == "requested":
                requested[version] = row.user_id
            else:
                saved[version] = row.user_id
        return releases, requested, saved

    def saved(self, procedure: str, sha256: str, user: str, path: str) -> None:
        """Someone saved this version on the Author page: they may not release it."""
        self._add(_row(procedure, "saved", sha256, user, path))

    def request(self, procedure: str, sha256: str, user: str, path: str) -> VersionState:
        """``user`` asks a second operator to review and release this version."""
        state = self.state(procedure, sha256)
        refusal = _request_refusal(state, path)
        if refusal is not None:
            raise ReleaseRefused(refusal)
        self._add(_row(procedure, "requested", sha256, user, path))
        log.info("%s asked for the release of %s (sha256 %s)", user, path, sha256)
        return self.state(procedure, sha256)

    def release(self, procedure: str, sha256: str, user: str, path: str, content: str) -> Release:
        """``user`` reviewed this version and releases it; ReleaseRefused says why they may not."""
        state = self.state(procedure, sha256)
        refusal = _release_refusal(state, user, path)
        if refusal is not None:
            raise ReleaseRefused(refusal)
        return self._release(state, procedure, user, path, content)

    def release_by_two(
        self, procedure: str, sha256: str, author: str, approver: str, path: str, content: str
    ) -> Release:
        """``author`` asks for this version's release and ``approver`` reviewed and releases it, in one
        act (``caretaker release``): the rules of :meth:`request` and :meth:`release`, all checked
        before a row is written, so a refused act leaves nothing behind. A request ``author``
        already made (on the Author page) is the one this release answers."""
        state = self.state(procedure, sha256)
        asked = state.requested_by == author
        refusal = None if asked else _request_refusal(state, path)
        if refusal is None:
            refusal = _release_refusal(replace(state, requested_by=author), approver, path)
        if refusal is not None:
            raise ReleaseRefused(refusal)
        request = () if asked else (_row(procedure, "requested", sha256, author, path),)
        release = self._release(replace(state, requested_by=author), procedure, approver, path, content, *request)
        log.info("%s asked for the release of %s, %s released it", author, path, approver)
        return release

    def _release(
        self, state: VersionState, procedure: str, user: str, path: str, content: str, *before: dict[str, Any]
    ) -> Release:
        """Write the release of ``state``'s version by ``user`` (after the rows ``before``, in one transaction)."""
        number = (state.release.number if state.release else 0) + 1
        released = _row(procedure, "released", state.sha256, user, path, release=number, content=content)
        self._add(*before, released)
        log.info("%s released %s as release %d (sha256 %s)", user, path, number, state.sha256)
        return Release(procedure, number, state.sha256, user, released["at"], state.requested_by or "", path)

    def _add(self, *rows: dict[str, Any]) -> None:
        with self._engine.begin() as connection:
            for row in rows:
                connection.execute(insert(procedure_releases).values(**row))


def _row(procedure: str, kind: str, sha256: str, user: str, path: str, **more: Any) -> dict[str, Any]:
    """A ``procedure_releases`` row, stamped now."""
    return {
        "procedure": procedure,
        "kind": kind,
        "sha256": sha256,
        "user_id": user,
        "at": datetime.now(UTC),
        "path": path,
        **more,
    }


def _request_refusal(state: VersionState, path: str) -> str | None:
    """Why nobody may ask for the release of ``state``'s version now (None: they may)."""
    if state.released:
        return f"this version of {path} is released already"
    if state.requested_by is not None:
        return f"{state.requested_by} already asked for the release of this version of {path}"
    return None


def _release_refusal(state: VersionState, user: str, path: str) -> str | None:
    """Why ``user`` may not release ``state``'s version (None: they may): someone asked for it, and
    the releaser is a second operator, neither who asked nor who saved it."""
    if state.released and state.release is not None:
        return f"{path} is release {state.release.number} already"
    if state.requested_by is None:
        return (
            f"nobody asked for the release of this version of {path}: ask for it first, "
            "then a second operator reviews and releases it"
        )
    for who, did in ((state.requested_by, "asked for its release"), (state.saved_by, "saved it")):
        if who == user:
            return f"{user} {did}: a second operator must review and release this version of {path}, not {user}"
    return None


def resume_refusal(checked: CheckedProcedure, shown: str, started: Payload, side: RobotSide) -> str | None:
    """Why a run whose first event recorded ``started`` may not be resumed with ``checked`` (None:
    it may): it goes on with the version it started with, and a rehearsal stays on a simulator."""
    if not isinstance(started, RunStarted):
        return "its log does not begin with its start"
    sha = started.sha256
    if sha is not None and sha != procedure_digest(checked):
        return f"{shown} changed since the run started (sha256 {short(sha)} → {short(procedure_digest(checked))})"
    if started.rehearsal:
        refusal = side.rehearsal_refusal()
        if refusal is not None:
            return f"the run is a rehearsal: {refusal}"
    return None


def version_for_run(
    store: ReleaseStore, checked: CheckedProcedure, shown: str, side: RobotSide, *, rehearsal: bool
) -> RunVersion:
    """The version a run of ``checked`` (named ``shown`` in messages) would run, if it may start.

    Raises:
        ReleaseRefused: a draft or a changed file outside a rehearsal, or a rehearsal against a
            robot side that is no simulator; the message says what to do.
    """
    sha = procedure_digest(checked)
    state = store.state(checked.procedure.id, sha)
    release = state.release
    if rehearsal:
        refusal = side.rehearsal_refusal()
        if refusal is not None:
            raise ReleaseRefused(f"{shown} cannot run as a rehearsal: {refusal}")
        return RunVersion(sha, release.number if state.released and release else None, True)
    if state.released and release is not None:
        return RunVersion(sha, release.number, False)
    if release is None:
        raise ReleaseRefused(
            f"{shown} is a draft (never released): a second operator reviews and releases it on the Author "
            "page, or run it as a rehearsal on a simulator"
        )
    raise ReleaseRefused(
        f"{shown} changed since release {release.number} (sha256 {short(release.sha256)} → {short(sha)}); "
        "release it again or run it as a rehearsal"
    )
