"""Released procedures: a second operator releases a version; a run of a draft or of a file changed
since its release is refused unless it rehearses on a simulator. SQLite and PostgreSQL in turn,
and a database from before the releases table upgraded to it."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from alembic import command
from sqlalchemy import create_engine, select

from pride.robot_sides import RobotSide
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog, database_url
from records.audit_schema import _config, head_revision
from records.releases import (
    ReleaseRefused,
    ReleaseStore,
    RunVersion,
    procedure_digest,
    procedure_releases,
    version_for_run,
)
from support.audit import AuditDatabase
from support.procedures import FIXTURES

SIMULATOR = RobotSide(Path("lab.yaml"), Path("lab-deployment.yaml"), simulator=True)
ROBOT = RobotSide(Path("lab.yaml"), Path("habitat.yaml"), simulator=False)


@pytest.fixture
def shelf(tmp_path: Path) -> Path:
    """The lab procedure and the sub-procedure it calls, in a folder of their own (edited by tests)."""
    for name in ("lab_all_kinds.xml", "lab_sub.xml"):
        shutil.copy(FIXTURES / name, tmp_path / name)
    return tmp_path


def test_a_second_operator_releases_and_a_run_records_the_version(
    database: AuditDatabase, shelf: Path, sysreps: dict[str, SysRep]
) -> None:
    log = AuditLog(database.url)
    store = ReleaseStore(log.engine)
    path = shelf / "lab_all_kinds.xml"
    checked = check_procedure(path, sysreps)
    sha = procedure_digest(checked)
    procedure = checked.procedure.id

    with pytest.raises(ReleaseRefused, match=r"lab_all_kinds.xml is a draft \(never released\)"):
        version_for_run(store, checked, "lab_all_kinds.xml", ROBOT, rehearsal=False)
    with pytest.raises(ReleaseRefused, match="nobody asked for the release"):
        store.release(procedure, sha, "bob", path.name, path.read_text())
    store.saved(procedure, sha, "carol", path.name)
    store.request(procedure, sha, "alice", path.name)
    with pytest.raises(ReleaseRefused, match="alice asked for its release: a second operator must review"):
        store.release(procedure, sha, "alice", path.name, path.read_text())
    with pytest.raises(ReleaseRefused, match="carol saved it: a second operator must review"):
        store.release(procedure, sha, "carol", path.name, path.read_text())
    release = store.release(procedure, sha, "bob", path.name, path.read_text())
    assert (release.number, release.released_by, release.requested_by) == (1, "bob", "alice")
    with log.engine.connect() as connection:  # the release keeps the text that was reviewed
        kept = connection.execute(select(procedure_releases.c.content).where(procedure_releases.c.release == 1))
        assert kept.scalar_one() == path.read_text()
    assert version_for_run(store, checked, path.name, ROBOT, rehearsal=False) == RunVersion(sha, 1, False)

    # a sub-procedure edited after the release changes the version: refused with both hashes
    (shelf / "lab_sub.xml").write_text((shelf / "lab_sub.xml").read_text().replace("</procedure>", "\n</procedure>"))
    changed = check_procedure(path, sysreps)
    new_sha = procedure_digest(changed)
    assert new_sha != sha
    with pytest.raises(ReleaseRefused) as refused:
        version_for_run(store, changed, "procedures/lab_all_kinds.xml", ROBOT, rehearsal=False)
    assert str(refused.value) == (
        f"procedures/lab_all_kinds.xml changed since release 1 (sha256 {sha[:8]}… → {new_sha[:8]}…); "
        "release it again or run it as a rehearsal"
    )
    with pytest.raises(ReleaseRefused, match="a rehearsal runs only against a simulator, and habitat.yaml is not one"):
        version_for_run(store, changed, path.name, ROBOT, rehearsal=True)
    assert version_for_run(store, changed, path.name, SIMULATOR, rehearsal=True) == RunVersion(new_sha, None, True)

    store.request(procedure, new_sha, "bob", path.name)
    assert store.release(procedure, new_sha, "alice", path.name, path.read_text()).number == 2
    assert store.state(procedure, new_sha).released
    assert not store.state(procedure, sha).released  # the older version is no longer the release
    log.close()


def test_a_database_from_before_releases_is_upgraded_to_them(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'audit.db'}"
    engine = create_engine(database_url(url))
    with engine.begin() as connection:
        command.upgrade(_config(connection), "0004")
    engine.dispose()
    log = AuditLog(url)
    assert log.schema_revision() == head_revision() >= "0005"
    store = ReleaseStore(log.engine)
    store.request("p", "ab" * 32, "alice", "p.xml")
    assert store.release("p", "ab" * 32, "bob", "p.xml", "<procedure/>").number == 1
    log.close()
