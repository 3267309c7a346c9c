"""One act of two operators (``caretaker release``) against the Author page's history: the same
rules, whichever place a request or a save was made, and a refused act writes nothing."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import func, select

from records.audit_log import AuditLog
from records.releases import ReleaseRefused, ReleaseStore, procedure_releases

SHA = "ab" * 32
OTHER = "cd" * 32


@pytest.fixture
def log(tmp_path: Path) -> Iterator[AuditLog]:
    audit = AuditLog(f"sqlite:///{tmp_path / 'ground.db'}")
    yield audit
    audit.close()


def _rows(log: AuditLog) -> int:
    with log.engine.connect() as connection:
        return int(connection.execute(select(func.count()).select_from(procedure_releases)).scalar_one())


def test_the_author_page_and_the_command_line_keep_one_set_of_rules(log: AuditLog) -> None:
    store = ReleaseStore(log.engine)
    # bob saved this version on the Author page: he may not approve it from the command line either
    store.saved("p", SHA, "bob", "p.xml")
    with pytest.raises(ReleaseRefused, match="bob saved it: a second operator must review"):
        store.release_by_two("p", SHA, "alice", "bob", "p.xml", "<procedure/>")
    with pytest.raises(ReleaseRefused, match="alice asked for its release: a second operator must review"):
        store.release_by_two("p", SHA, "alice", "alice", "p.xml", "<procedure/>")
    assert _rows(log) == 1  # only the save: a refused act leaves no request behind

    # carol asked on the Author page: only her request is answered, not another author's
    store.request("p", SHA, "carol", "p.xml")
    with pytest.raises(ReleaseRefused, match="carol already asked for the release of this version of p.xml"):
        store.release_by_two("p", SHA, "alice", "dave", "p.xml", "<procedure/>")
    release = store.release_by_two("p", SHA, "carol", "dave", "p.xml", "<procedure/>")
    assert (release.number, release.requested_by, release.released_by, release.path) == (1, "carol", "dave", "p.xml")
    assert _rows(log) == 3  # save, carol's request, dave's release: no second request
    with pytest.raises(ReleaseRefused, match="this version of p.xml is released already"):
        store.release_by_two("p", SHA, "carol", "dave", "p.xml", "<procedure/>")

    # a new version released in one act: a request and a release, listed after the first
    second = store.release_by_two("p", OTHER, "alice", "bob", "p.xml", "<procedure> </procedure>")
    assert second.number == 2 and store.state("p", OTHER).released and not store.state("p", SHA).released
    listed = [(r.procedure, r.number, r.sha256, r.requested_by, r.released_by) for r in store.releases()]
    assert listed == [("p", 1, SHA, "carol", "dave"), ("p", 2, OTHER, "alice", "bob")]
