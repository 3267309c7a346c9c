"""Released procedures: operators run a version a second operator reviewed; a draft only rehearses.

Why: an edited procedure file should not reach a robot before someone other than its author has
read it (as Epsilon3's released procedure versions). So a version is identified by its content
hash (:func:`procedure_digest`: the file and every sub-procedure it calls), and the ground database
keeps, per procedure id, an append-only history in ``procedure_releases``: who saved a version on
the Author page, who asked for a version's release, and who released it (with its text and a
release number, 1, 2, ...). Releasing needs a request, by someone else than the releaser; nobody
releases a version they saved or asked for themselves.

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
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import Column, DateTime, Integer, MetaData, String, Table, Text, insert, select
from sqlalchemy.engine import Engine

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
        with self._engine.connect() as connection:
            rows = connection.execute(
                select(procedure_releases)
                .where(procedure_releases.c.procedure == procedure)
                .order_by(procedure_releases.c.id)
            ).all()
        release = None
        requested: dict[str, str] = {}
        saved: dict[str, str] = {}
        for row in rows:
            if row.kind == "released":
                release = Release(
                    procedure, row.release, row.sha256, row.user_id, row.at, requested.get(row.sha256, "")
                )
                requested.pop(row.sha256, None)
            elif row.kind == "requested":
                requested[row.sha256] = row.user_id
            else:
                saved[row.sha256] = row.user_id
        return VersionState(sha256, release, requested.get(sha256), saved.get(sha256))

    def saved(self, procedure: str, sha256: str, user: str, path: str) -> None:
        """Someone saved this version on the Author page: they may not release it."""
        self._add(procedure, "saved", sha256, user, path)

    def request(self, procedure: str, sha256: str, user: str, path: str) -> VersionState:
        """``user`` asks a second operator to review and release this version."""
        state = self.state(procedure, sha256)
        if state.released:
            raise ReleaseRefused(f"this version of {path} is released already")
        if state.requested_by is not None:
            raise ReleaseRefused(f"{state.requested_by} already asked for the release of this version of {path}")
        self._add(procedure, "requested", sha256, user, path)
        log.info("%s asked for the release of %s (sha256 %s)", user, path, sha256)
        return self.state(procedure, sha256)

    def release(self, procedure: str, sha256: str, user: str, path: str, content: str) -> Release:
        """``user`` reviewed this version and releases it; ReleaseRefused says why they may not."""
        state = self.state(procedure, sha256)
        if state.released and state.release is not None:
            raise ReleaseRefused(f"{path} is release {state.release.number} already")
        if state.requested_by is None:
            raise ReleaseRefused(
                f"nobody asked for the release of this version of {path}: ask for it first, "
                "then a second operator reviews and releases it"
            )
        for who, did in ((state.requested_by, "asked for its release"), (state.saved_by, "saved it")):
            if who == user:
                raise ReleaseRefused(
                    f"{user} {did}: a second operator must review and release this version of {path}, not {user}"
                )
        number = (state.release.number if state.release else 0) + 1
        self._add(procedure, "released", sha256, user, path, release=number, content=content)
        log.info("%s released %s as release %d (sha256 %s)", user, path, number, sha256)
        return Release(procedure, number, sha256, user, datetime.now(UTC), state.requested_by)

    def _add(self, procedure: str, kind: str, sha256: str, user: str, path: str, **more: Any) -> None:
        with self._engine.begin() as connection:
            connection.execute(
                insert(procedure_releases).values(
                    procedure=procedure, kind=kind, sha256=sha256, user_id=user, at=datetime.now(UTC), path=path, **more
                )
            )


def resume_refusal(checked: CheckedProcedure, shown: str, started: Mapping[str, Any], side: RobotSide) -> str | None:
    """Why a run whose ``run_started`` recorded ``started`` may not be resumed with ``checked`` (None:
    it may): it goes on with the version it started with, and a rehearsal stays on a simulator."""
    sha = started.get("sha256")
    if sha is not None and sha != procedure_digest(checked):
        return f"{shown} changed since the run started (sha256 {short(str(sha))} → {short(procedure_digest(checked))})"
    if started.get("rehearsal"):
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
