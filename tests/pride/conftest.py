"""Fixtures of the procedure-side tests: SysReps, audit-log databases and journals, the executive on the lab bench.

Their helpers (lab gateway, audit databases, waiting on runs) are in tests/support.
"""

from __future__ import annotations

import contextlib
import itertools
import json
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import pytest

from pride.approvals import ApprovalPolicy
from pride.events import Event
from pride.executive import Executive, Mode, OperatorActionError, RunStatus
from pride.run_setup import load_sysreps
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog
from records.robot_control import RobotControl
from support.audit import AuditDatabase, RecordedJournal
from support.executive_runs import TIMEOUT, Bench
from support.lab_gateway import LabGateway
from support.postgres import OWNER, RUNNER, PostgresServer
from support.procedures import FIXTURES, REPO


@pytest.fixture(scope="session")
def sysreps() -> dict[str, SysRep]:
    """The repository's SysReps plus the lab bench's."""
    return load_sysreps([REPO / "sysrep", FIXTURES / "sysrep"])


# ---- the audit log's database: every suite that records runs runs on SQLite and on PostgreSQL ----


@pytest.fixture(scope="session")
def audit_template(postgres: PostgresServer) -> str:
    """A database at the newest schema revision, copied for each test (cheaper than migrating each)."""
    name = postgres.new_database()
    AuditLog(postgres.url(name, OWNER)).close()
    return name


@pytest.fixture(params=["sqlite", "postgresql"])
def new_database(request: pytest.FixtureRequest, tmp_path: Path) -> Callable[..., AuditDatabase]:
    """Make audit-log databases of the parametrized kind: migrated, or ``empty=True`` (no schema at all)."""
    names = itertools.count(1)

    def make(*, empty: bool = False) -> AuditDatabase:
        if request.param == "sqlite":
            url = f"sqlite:///{tmp_path / f'audit-{next(names)}.db'}"
            if not empty:
                AuditLog(url).close()
            return AuditDatabase("sqlite", url, url)
        server: PostgresServer = request.getfixturevalue("postgres")
        name = server.new_database(template=None if empty else request.getfixturevalue("audit_template"))
        return AuditDatabase("postgresql", server.url(name, RUNNER), server.url(name, OWNER), server, name)

    return make


@pytest.fixture
def database(new_database: Callable[..., AuditDatabase]) -> AuditDatabase:
    """One migrated audit-log database per test, SQLite and PostgreSQL in turn."""
    return new_database()


@pytest.fixture
def new_journal(new_database: Callable[..., AuditDatabase]) -> Iterator[Callable[..., RecordedJournal]]:
    """Journals on fresh databases; ``new_journal(log)`` starts from a crashed runner's ``log`` of a run.

    At teardown each database must hold exactly what was appended, in a chain that verifies.
    """
    made: list[RecordedJournal] = []

    def make(log: Sequence[Event] = ()) -> RecordedJournal:
        journal = RecordedJournal(AuditLog(new_database().url))
        for event in log:
            journal.log.append(event)
        journal.stored_before = list(log)
        made.append(journal)
        return journal

    yield make
    for journal in made:
        expected = journal.stored_before + journal.events
        for run_id in sorted({e.run_id for e in expected}):
            stored = [_comparable(e) for e in journal.log.events(run_id)]
            assert stored == [_comparable(e) for e in expected if e.run_id == run_id]
            check = journal.log.verify(run_id)
            assert check.ok, check.describe()
        journal.log.close()


def _comparable(event: Event) -> dict[str, object]:
    """An event as it reads back from the database (data through JSON)."""
    return json.loads(json.dumps(event.to_dict(), default=str))


# ---- the executive on the lab bench -------------------------------------------------------------


@pytest.fixture
def bench(tmp_path: Path, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]) -> Iterator[Bench]:
    """``bench(mode, name, gateway, run_id=, control=, approvals=)``: an executive on the lab bench
    gateway, its journal on a fresh audit log (SQLite and PostgreSQL in turn); ``control=True`` puts
    it under robot control in that log's database; ``approvals`` its critical commanding. Live runs
    are stopped at teardown."""
    made: list[Executive] = []
    controls: list[RobotControl] = []

    def make(
        mode: Mode = Mode.AUTONOMOUS,
        name: str = "lab_all_kinds.xml",
        gateway: LabGateway | None = None,
        *,
        run_id: str = "run-1",
        control: RobotControl | bool = False,
        journal: RecordedJournal | None = None,
        approvals: ApprovalPolicy | None = None,
    ) -> tuple[Executive, LabGateway, RecordedJournal]:
        gateway = gateway or LabGateway(str(tmp_path / "images"))
        journal = journal or new_journal()
        if control is True:
            control = RobotControl(journal.log.url)
            controls.append(control)
        executive = Executive(
            check_procedure(FIXTURES / name, sysreps),
            gateway,
            journal,
            run_id=run_id,
            mode=mode,
            control=control or None,
            approvals=approvals,
        )
        made.append(executive)
        return executive, gateway, journal

    yield make
    for executive in made:
        if executive.snapshot().status is RunStatus.ACTIVE:
            with contextlib.suppress(OperatorActionError):  # a run whose journal a test broke stops by itself
                executive.stop("teardown")
        executive.join(TIMEOUT)
    for control in controls:
        control.close()
