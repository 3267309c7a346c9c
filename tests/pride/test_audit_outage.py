"""PostgreSQL goes away in the middle of a run: the run waits, says so, and goes on in order when the
database is back; past the outage budget it stops with the reason and resumes from the log.

A real server (tests/support/postgres.py) is stopped and started while the lab bench's ``capture``
command is in flight, so the command's result is the first event that cannot be stored.
"""

from __future__ import annotations

import logging
import queue
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from pride.events import EventKind
from pride.executive import Executive, Hold, Mode, RunStatus, Snapshot
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog, Availability
from support.lab_gateway import LabGateway
from support.postgres import RUNNER, PostgresServer
from support.procedures import FIXTURES

TIMEOUT = 30.0
PROCEDURE = FIXTURES / "lab_all_kinds.xml"


@pytest.fixture
def outage(postgres: PostgresServer, audit_template: str) -> Iterator[PostgresServer]:
    """The session's server, started again if a test left it stopped."""
    yield postgres
    if not postgres.running():
        postgres.start()


def drive(executive: Executive, until: Callable[[Snapshot], bool]) -> Snapshot:
    """Answer every hold as the operator would until ``until`` holds or the run ends."""
    answers = {
        Hold.OPERATOR_INPUT: lambda: executive.enter("alice", "dock"),
        Hold.CONFIRMATION: lambda: executive.confirm("alice"),
        Hold.OPERATOR_ACTION: lambda: executive.mark_done("alice"),
        Hold.IN_FLIGHT: lambda: executive.retry("alice"),
    }
    while True:
        snap = executive.wait_for(lambda s: until(s) or s.hold is not None or s.status is not RunStatus.ACTIVE, TIMEOUT)
        assert snap is not None, "the run neither held, ended, nor reached the point awaited"
        if until(snap) or snap.status is not RunStatus.ACTIVE:
            return snap
        answers[snap.hold]()


def capturing(snap: Snapshot) -> bool:
    return snap.executing and snap.current == "2.3"


def start_run(
    url: str, tmp_path: Path, sysreps: dict[str, SysRep], *, budget: float
) -> tuple[Executive, LabGateway, AuditLog, queue.Queue[tuple[Availability, int]]]:
    """A run held with ``capture`` in flight; the queue gets each availability change with the commands sent by then."""
    log = AuditLog(url, outage_budget=budget)
    gateway = LabGateway(str(tmp_path / "images"))
    states: queue.Queue[tuple[Availability, int]] = queue.Queue()
    log.add_availability_listener(lambda state: states.put((state, len(gateway.sent))))
    gateway.block.add("capture")
    executive = Executive(check_procedure(PROCEDURE, sysreps), gateway, log, run_id="outage-run", mode=Mode.AUTONOMOUS)
    executive.start("alice")
    assert drive(executive, capturing).status is RunStatus.ACTIVE
    assert gateway.blocking.wait(TIMEOUT)  # capture is in flight, so its command_sent is stored (durable first)
    return executive, gateway, log, states


def test_a_postgresql_restart_mid_run_makes_the_run_wait_then_go_on_with_nothing_lost(
    outage: PostgresServer,
    audit_template: str,
    tmp_path: Path,
    sysreps: dict[str, SysRep],
    caplog: pytest.LogCaptureFixture,
) -> None:
    url = outage.url(outage.new_database(template=audit_template), RUNNER)
    executive, gateway, log, states = start_run(url, tmp_path, sysreps, budget=120)

    outage.stop()
    gateway.release.set()  # capture answers now; its result cannot be stored
    down, sent_when_down = states.get(timeout=TIMEOUT)
    assert not down.available and down.since is not None and down.error
    assert log.availability == down
    assert any("unavailable since" in r.getMessage() and r.levelno == logging.WARNING for r in caplog.records)
    outage.start()
    up, sent_when_up = states.get(timeout=TIMEOUT)
    assert up.available and log.availability.available
    assert sent_when_up == sent_when_down and gateway.sent[sent_when_down - 1][1] == "capture"  # PAX waited
    assert any("available again" in r.getMessage() for r in caplog.records)

    final = drive(executive, lambda s: False)
    executive.join(TIMEOUT)
    assert final.status is RunStatus.COMPLETED, final
    events = log.events("outage-run")
    assert [e.seq for e in events] == list(range(1, len(events) + 1))  # no gap, nothing twice
    results = [e for e in events if e.kind is EventKind.COMMAND_RESULT and e.instruction == "2.3"]
    assert len(results) == 1 and results[0].data.to_json()["success"] is True
    after = [e.kind for e in events[events.index(results[0]) - 1 :]]
    assert after[:2] == [EventKind.COMMAND_SENT, EventKind.COMMAND_RESULT]  # the waiting event kept its place
    assert Counter(c for _, c, _ in gateway.sent)["capture"] == 1
    check = log.verify("outage-run")
    assert check.ok and check.events == len(events), check.describe()
    log.close()


def test_an_outage_longer_than_the_budget_stops_the_run_with_the_reason_and_resume_completes_it(
    outage: PostgresServer, audit_template: str, tmp_path: Path, sysreps: dict[str, SysRep]
) -> None:
    url = outage.url(outage.new_database(template=audit_template), RUNNER)
    executive, gateway, log, states = start_run(url, tmp_path, sysreps, budget=1.0)

    outage.stop()
    gateway.release.set()
    assert not states.get(timeout=TIMEOUT)[0].available
    stopped = executive.wait_for(lambda s: s.status is not RunStatus.ACTIVE, TIMEOUT)
    assert stopped is not None and stopped.status is RunStatus.STOPPED
    assert stopped.error and "unavailable since" in stopped.error and "gave up after" in stopped.error
    executive.join(TIMEOUT)
    log.close()

    outage.start()
    log = AuditLog(url)
    logged = log.events("outage-run")
    assert logged[-1].kind is EventKind.COMMAND_SENT and logged[-1].instruction == "2.3"  # its result never stored
    # the same habitat: the capture's key is sent again by itself and its recorded outcome comes back
    resumed = Executive.resume(check_procedure(PROCEDURE, sysreps), gateway, log, logged, "bob")
    final = drive(resumed, lambda s: False)
    resumed.join(TIMEOUT)
    assert final.status is RunStatus.COMPLETED, final
    assert Counter(c for _, c, _ in gateway.sent)["capture"] == 1 and gateway.resent == [
        logged[-1].data.to_json()["key"]
    ]
    events = log.events("outage-run")
    result = next(e for e in events if e.kind is EventKind.COMMAND_RESULT and e.instruction == "2.3")
    assert (result.actor, result.data.to_json()["outcome"]) == ("PAX", "succeeded")
    assert [e.seq for e in events] == list(range(1, len(events) + 1))
    assert log.verify("outage-run").ok
    log.close()
