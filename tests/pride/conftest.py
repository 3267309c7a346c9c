"""Shared pieces of the procedure-side tests: SysReps, lab procedures, lab gateway, audit log databases."""

from __future__ import annotations

import contextlib
import itertools
import json
import sqlite3
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
FIXTURES = HERE / "fixtures"
sys.path.insert(0, str(HERE))  # lab_gateway is importable here and in runner subprocesses

from lab_gateway import LabGateway  # noqa: E402

from pride.audit_log import AuditLog, Availability  # noqa: E402
from pride.events import Event, EventKind  # noqa: E402
from pride.executive import Executive, Hold, Mode, OperatorActionError, RunStatus, Snapshot  # noqa: E402
from pride.lint import check_procedure  # noqa: E402
from pride.robot_control import RobotControl  # noqa: E402
from pride.sysrep import SysRep, load_sysrep_dir  # noqa: E402
from support.postgres import OWNER, RUNNER, PostgresServer  # noqa: E402


@pytest.fixture(scope="session")
def sysreps() -> dict[str, SysRep]:
    """The repository's SysReps plus the lab bench's."""
    return {**load_sysrep_dir(REPO / "sysrep"), **load_sysrep_dir(FIXTURES / "sysrep")}


# ---- the audit log's database: every suite that records runs runs on SQLite and on PostgreSQL ----


@dataclass
class AuditDatabase:
    """One empty-of-events audit-log database: ``url`` is the runner's, ``owner_url`` the schema owner's."""

    kind: str
    url: str
    owner_url: str
    server: PostgresServer | None = None
    name: str = ""

    def tamper(self, *statements: str) -> None:
        """Run SQL with every protection bypassed, as a database superuser (or the SQLite file's owner) could."""
        if self.server is not None:
            self.server.sql("SET session_replication_role = replica", *statements, database=self.name)
            return
        with closing(sqlite3.connect(self.url.removeprefix("sqlite:///"), isolation_level=None)) as connection:
            connection.execute("DROP TRIGGER audit_records_no_update")
            connection.execute("DROP TRIGGER audit_records_no_delete")
            for statement in statements:
                connection.execute(statement)


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


class RecordedJournal:
    """The audit log as the executive's journal, remembering what went through it for assertions."""

    def __init__(self, log: AuditLog) -> None:
        self.log = log
        self.events: list[Event] = []
        self.stored_before: list[Event] = []
        self.fail_with: Exception | None = None  # set to make every append fail (a runner's last moments)

    def append(self, event: Event) -> None:
        if self.fail_with is not None:
            raise self.fail_with
        self.log.append(event)
        self.events.append(event)

    @property
    def availability(self) -> Availability:
        return self.log.availability

    def kinds(self, number: str | None = None) -> list[EventKind]:
        return [e.kind for e in self.events if number is None or e.instruction == number]


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

TIMEOUT = 20.0


@pytest.fixture
def bench(tmp_path: Path, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]):
    """``bench(mode, name, gateway, run_id=, control=)``: an executive on the lab bench gateway, its
    journal on a fresh audit log (SQLite and PostgreSQL in turn); ``control=True`` puts it under
    robot control in that log's database. Live runs are stopped at teardown."""
    made: list[Executive] = []
    controls: list[RobotControl] = []

    def make(mode: Mode = Mode.AUTONOMOUS, name: str = "lab_all_kinds.xml", gateway: LabGateway | None = None, *,
             run_id: str = "run-1", control: RobotControl | bool = False, journal: RecordedJournal | None = None):
        gateway = gateway or LabGateway(str(tmp_path / "images"))
        journal = journal or new_journal()
        if control is True:
            control = RobotControl(journal.log.url)
            controls.append(control)
        executive = Executive(check_procedure(FIXTURES / name, sysreps), gateway, journal, run_id=run_id, mode=mode,
                              control=control or None)
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


def held(executive: Executive, hold: Hold, at: str) -> Snapshot:
    """The run's snapshot once it holds; it must hold with ``hold`` at ``at``."""
    snap = executive.wait_for(lambda s: s.hold is not None or s.status is not RunStatus.ACTIVE, TIMEOUT)
    assert snap is not None, "the run neither held nor ended"
    assert (snap.hold, snap.current) == (hold, at), snap
    return snap


def finished(executive: Executive) -> Snapshot:
    snap = executive.wait_for(lambda s: s.status is not RunStatus.ACTIVE, TIMEOUT)
    assert snap is not None
    return snap
