"""Released versions on the Author page: who saved a version, who asks for its release, who releases it.

A version is the procedure file's content hash with its sub-procedures
(:func:`records.releases.procedure_digest`); the history is kept by
:class:`records.releases.ReleaseStore`. An operator acts on the version they saw (``seen``): if
the file changed since, the request or release is refused (409) so nobody releases what they
did not read.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from console.actions import ActionRefused
from console.catalog import Catalog
from procedure_language.lint import CheckedProcedure
from records.releases import ReleaseRefused, ReleaseStore, procedure_digest, short

__all__ = ["ReleaseDesk"]


class ReleaseDesk:
    """The release history of the catalog's procedures; ``check`` reads and checks one by file
    name (ActionRefused 422 listing its problems)."""

    def __init__(self, catalog: Catalog, releases: ReleaseStore, check: Callable[[str], CheckedProcedure]) -> None:
        self.catalog = catalog
        self.releases = releases
        self._check = check

    def version_state(self, procedure_name: str) -> dict[str, Any]:
        """Where the procedure's file stands: its version's hash, its newest release, a request."""
        checked = self._check(procedure_name)
        state = self.releases.state(checked.procedure.id, procedure_digest(checked))
        return {"procedure": checked.procedure.id, "name": procedure_name, **state.to_json()}

    def saved(self, user: str, procedure_name: str) -> None:
        """``user`` saved the procedure on the Author page: they may not release this version."""
        checked = self._check(procedure_name)
        self.releases.saved(checked.procedure.id, procedure_digest(checked), user, self.catalog.shown(procedure_name))

    def ask_release(self, user: str, procedure_name: str, seen: str) -> dict[str, Any]:
        """``user`` asks a second operator to review and release the version they saw (``seen``: its hash)."""
        checked = self._current(procedure_name, seen)
        try:
            self.releases.request(checked.procedure.id, seen, user, self.catalog.shown(procedure_name))
        except ReleaseRefused as exc:
            raise ActionRefused(409, str(exc)) from None
        return self.version_state(procedure_name)

    def release(self, user: str, procedure_name: str, seen: str) -> dict[str, Any]:
        """``user`` reviewed the version they saw (``seen``: its hash) and releases it."""
        checked = self._current(procedure_name, seen)
        path = self.catalog.procedure_path(procedure_name)
        try:
            self.releases.release(
                checked.procedure.id, seen, user, self.catalog.shown(procedure_name), path.read_text(encoding="utf-8")
            )
        except ReleaseRefused as exc:
            raise ActionRefused(409, str(exc)) from None
        return self.version_state(procedure_name)

    def _current(self, procedure_name: str, seen: str) -> CheckedProcedure:
        """The procedure, if its file is still the version the operator saw (ActionRefused 409 if not)."""
        checked = self._check(procedure_name)
        now = procedure_digest(checked)
        if now != seen:
            raise ActionRefused(
                409,
                f"{self.catalog.shown(procedure_name)} changed since you opened it (sha256 {short(seen)} → "
                f"{short(now)}): open it again and review what is there now",
            )
        return checked
