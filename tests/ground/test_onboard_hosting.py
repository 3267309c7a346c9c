"""An onboard run hosted for the consoles by the runner that supervises it.

A real SQLite ground database and change feed; a :class:`TerminalHost` hosting an
:class:`OnboardView` as ``caretaker run --onboard`` does, another "console" reading it and
forwarding actions through the database. The link to the habitat is the test's ``send``: what
the runner would send up, and the habitat's answer (the habitat's side: tests/onboard, and the
browser over the emulated link: tests/flight/test_iva_onboard_halt.py).
"""

from __future__ import annotations

import tempfile
import threading
import time
from collections.abc import Iterator, Mapping
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from console.accounts import AccountStore
from console.actions import ActionRefused
from console.attach import attach
from console.catalog import Catalog
from console.onboard_launch import LaunchRefused, launch_onboard
from console.onboard_view import OnboardView
from console.run_board import RunBoard
from console.terminal_host import TerminalHost
from ground.action_requests import ActionRequests, Answer, ForwardedAction
from ground.change_feed import open_change_feed
from ground.run_hosts import RunHosting
from pride.events import Event, EventKind
from procedure_language.lint import check_procedure
from procedure_language.sysrep import load_sysrep_dir
from records.audit_log import AuditLog
from support.audit import attach_records
from support.procedures import REPO

PROCEDURE = REPO / "procedures" / "iva_cdra_filter_replacement.xml"
RUN = "iva-onboard-1"


@pytest.fixture
def audit(tmp_path: Path) -> Iterator[AuditLog]:
    log = AuditLog(f"sqlite:///{tmp_path / 'ground.db'}")
    accounts = AccountStore(log.url)
    accounts.add("alice", "operator", "alice-password-1")
    accounts.add("olga", "observer", "olga-password-1")
    accounts.close()
    yield log
    log.close()


class Habitat:
    """What the runner would send up, and what the habitat answers (``answers``: by action)."""

    def __init__(self) -> None:
        self.sent: list[tuple[str, str, dict[str, Any]]] = []
        self.answers: dict[str, tuple[str, str]] = {}

    def __call__(self, action: str, user: str, args: Mapping[str, Any], on_its_way: object = None) -> tuple[str, str]:
        self.sent.append((action, user, dict(args)))
        return self.answers.get(action, ("DONE", f"{action} by {user}"))


@pytest.fixture
def hosted(audit: AuditLog) -> Iterator[tuple[TerminalHost, OnboardView, Habitat]]:
    sysreps = load_sysrep_dir(REPO / "sysrep")
    checked = check_procedure(str(PROCEDURE), sysreps)
    host = TerminalHost(audit, binding="iva-ground.yaml", name="runner at the bench")
    view = OnboardView(
        RUN,
        checked.procedure,
        binding="iva-ground.yaml",
        started_by="alice",
        mode="autonomous",
        sysreps=dict(checked.sysreps),
        host="runner at the bench (supervising; the habitat runs it)",
        on_change=lambda: host.changed(RUN),
    )
    habitat = Habitat()
    host.host_onboard(view, habitat)
    yield host, view, habitat
    host.close()


def forward(audit: AuditLog, host: TerminalHost, user: str, action: dict[str, Any]) -> Answer:
    """What a console does with an action on a run hosted elsewhere."""
    asker = ActionRequests(audit.engine, host_id="console-b", console="console B", perform=_never)
    feed = open_change_feed(audit.engine)
    feed.subscribe(asker.notice)
    try:
        assert feed.connected.wait(10)
        return asker.forward(RUN, host.hosting.host_id, user, action)
    finally:
        feed.close()
        asker.close()


def _never(request: ForwardedAction) -> Answer:
    raise AssertionError(f"nothing is hosted on console B: {request}")


def test_actions_go_up_as_the_operator_who_clicked_with_the_instruction_they_clicked_on(
    audit: AuditLog, hosted: tuple[TerminalHost, OnboardView, Habitat]
) -> None:
    host, _, habitat = hosted
    halted = forward(audit, host, "alice", {"action": "halt", "reason": "crew at the cabinet"})
    assert halted == Answer(200, {"ok": True, "action": "halt", "result": "on the habitat: halt by alice"})
    entered = forward(audit, host, "alice", {"action": "enter", "instruction": "4.1", "value": "CDRA-F-0012"})
    assert entered.ok
    assert habitat.sent == [
        ("halt", "alice", {"reason": "crew at the cabinet"}),
        ("enter", "alice", {"instruction": "4.1", "value": "CDRA-F-0012"}),
    ]


def test_what_the_habitat_refuses_or_does_not_answer_is_said_and_nothing_else_goes_up(
    audit: AuditLog, hosted: tuple[TerminalHost, OnboardView, Habitat]
) -> None:
    host, _, habitat = hosted
    habitat.answers["done"] = ("REFUSED", "done was for 2.6, the run is at 2.7: not acted on")
    habitat.answers["pause"] = ("UNKNOWN", "sent; no answer from the habitat within 25 s (see the log)")
    refused = forward(audit, host, "alice", {"action": "done", "instruction": "2.6"})
    assert refused == Answer(
        409, {"error": "the habitat refused it: done was for 2.6, the run is at 2.7: not acted on"}
    )
    unknown = forward(audit, host, "alice", {"action": "pause"})
    assert unknown.status == 504 and unknown.body["error"].startswith("outcome unknown: sent; no answer")
    # refused on the ground, before anything is sent
    observer = forward(audit, host, "olga", {"action": "halt"})
    assert observer.status == 403 and "observers may watch, not act" in observer.body["error"]
    mode = forward(audit, host, "alice", {"action": "mode", "mode": "manual"})
    assert mode.status == 409 and mode.body["error"].startswith(
        "mode is not taken by an onboard run (the habitat takes: halt,"
    )
    unnumbered = forward(audit, host, "alice", {"action": "retry"})
    assert unnumbered == Answer(400, {"error": "retry needs the instruction number"})
    assert [action for action, _, _ in habitat.sent] == ["done", "pause"]


def test_consoles_see_what_came_down_and_since_when_the_habitat_is_silent(
    audit: AuditLog, hosted: tuple[TerminalHost, OnboardView, Habitat]
) -> None:
    _, view, _ = hosted
    reader = RunHosting(audit.engine, host="console B")
    try:
        start = datetime.now(UTC) - timedelta(seconds=2)
        view.event(Event(RUN, 1, EventKind.RUN_STARTED, "alice", None, {"procedure": "iva"}, start))
        snapshot = {"status": "active", "mode": "autonomous", "current": "2.7", "hold": None, "last_seq": 1}
        view.news(snapshot=snapshot, habitat_time=start.isoformat(), heard=time.time(), waiting="", silent_since=None)
        state = _published_state(audit, reader, lambda s: s.get("onboard", {}).get("heard") is not None)
        assert state["status"] == "active" and state["current"] == "2.7" and state["link"] == {"state": "connected"}
        assert state["onboard"]["last_seq"] == 1 and state["onboard"]["last_event_age_s"] >= 2.0
        silent = time.time() - 30
        view.news(snapshot=None, habitat_time="", heard=silent, waiting="", silent_since=silent)
        state = _published_state(audit, reader, lambda s: s["link"]["state"] == "silent")
        assert state["link"]["since"] == datetime.fromtimestamp(silent, UTC).isoformat()
        assert state["current"] == "2.7"  # the last news, not a guess of what happened since
    finally:
        reader.close()


def _published_state(audit: AuditLog, reader: RunHosting, ready: Any = None, timeout: float = 30.0) -> dict[str, Any]:
    """The run's view as another console reads it from the database, once ``ready`` holds (read
    again at each change of the run's host row, as a console does)."""
    changed = threading.Event()
    feed = open_change_feed(audit.engine)
    feed.subscribe(lambda notice: changed.set() if notice.channel in ("hosts", "resync") else None)
    try:
        assert feed.connected.wait(10)
        deadline = time.monotonic() + timeout
        while True:
            changed.clear()
            published = reader.published(RUN)
            state = published[2].get("state") if published else None
            if state and (ready is None or ready(state)):
                return dict(state)
            assert changed.wait(deadline - time.monotonic()), f"no published view of {RUN} that holds: {state}"
    finally:
        feed.close()


def test_a_start_on_the_habitat_that_cannot_be_uplinked_says_why_and_leaves_nothing_running(
    audit: AuditLog, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The console's "run on the habitat" starts the supervising runner; one that ends before the
    habitat accepted the unit (here: a binding with no link secret to sign it with) is a refusal
    with the runner's own words, and names the runner's log, in the console's temporary folder."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # this process is the console here
    with pytest.raises(LaunchRefused) as refused:
        launch_onboard(
            PROCEDURE,
            REPO / "sysrep" / "bindings" / "iva.yaml",
            user="alice",
            autonomous=True,
            rehearsal=True,  # the shipped procedure is a draft in this database; the IVA robot side a simulator
            db_url=audit.url,
            sysreps=[REPO / "sysrep"],
            rosbridge=None,
        )
    said = str(refused.value)
    assert "iva.yaml has no security.secret_file: an onboard unit is signed with the link's secret" in said, said
    assert f"(runner log: {tmp_path}/caretaker-onboard-runner-" in said, said
    assert audit.runs() == []  # nothing started, nothing logged


def test_a_supervisor_gone_while_the_run_goes_on_is_offered_for_attach_and_an_attach_while_one_holds_it_is_refused(
    audit: AuditLog,
) -> None:
    """The runs list of a console (console B) and its attach (console/attach.py) against a runner
    that hosts an onboard run: refused, naming the runner, while it holds the run; offered once it
    stopped with the run going on; the attach then starts ``caretaker run --attach`` with the run's
    binding (here one without the link's secret, so the runner says why it cannot)."""
    sysreps = load_sysrep_dir(REPO / "sysrep")
    checked = check_procedure(str(PROCEDURE), sysreps)
    host = TerminalHost(audit, binding="iva.yaml", onboard=True, operator="alice")
    view = OnboardView(
        RUN,
        checked.procedure,
        binding="iva.yaml",
        started_by="alice",
        mode="autonomous",
        sysreps=dict(checked.sysreps),
        host=host.hosting.host,
        on_change=lambda: host.changed(RUN),
    )
    host.host_onboard(view, Habitat())
    started = Event(RUN, 1, EventKind.RUN_STARTED, "alice", None, {"procedure": "iva"}, datetime.now(UTC))
    audit.append(started)  # as the downlink stores what came down
    view.event(started)
    catalog = Catalog(REPO / "procedures", REPO / "sysrep" / "bindings", (REPO / "sysrep",))
    board = RunBoard(catalog, audit, accounts=AccountStore(audit.url), console="console B")
    try:
        reader = RunHosting(audit.engine, host="reader")
        try:
            _published_state(audit, reader, lambda s: s.get("onboard", {}).get("last_seq") == 1)
        finally:
            reader.close()
        (line,) = board.listing()
        assert line["host"] == host.hosting.host and "unsupervised" not in line  # supervised
        with pytest.raises(ActionRefused) as held:
            attach(board, "bob", RUN)
        assert held.value.status == 409 and held.value.details["held_by"]["host"] == host.hosting.host
        assert f"{RUN} has a supervisor: {host.hosting.host} holds it" in held.value.message
        assert host.hosting.host.endswith(" for alice")  # who answers at it
        assert attach_records(audit, RUN) == [
            (
                "action_refused",
                "bob",
                {"action": "attach", "rule": "one_supervisor", "reason": held.value.message, "asked": {"run": RUN}},
            )
        ]
        host.close()  # the supervisor stops; the habitat's run goes on
        (line,) = board.listing()
        assert line["status"] == "interrupted" and line["host_lost"]["host"] == host.hosting.host
        assert line["unsupervised"] == {"supervisor": host.hosting.host, "binding": "iva.yaml"}
        with pytest.raises(ActionRefused, match="runs on the habitat: attach a supervisor"):
            board.resume("bob", RUN, "iva.yaml", "manual")  # never a second executor of it on the ground
        with pytest.raises(ActionRefused) as failed:
            attach(board, "bob", RUN)
        assert failed.value.status == 502, failed.value.message
        assert "iva.yaml has no security.secret_file" in failed.value.message, failed.value.message
        assert len(attach_records(audit, RUN)) == 1  # the runner never attached: nothing more recorded
    finally:
        board.close()


def test_a_supervisor_whose_run_ended_or_never_started_leaves_no_row(audit: AuditLog) -> None:
    """Only a run that goes on on the habitat keeps its row after its supervisor: one whose end
    came down, or one that never started there (the unit refused), is gone from the hosts."""
    sysreps = load_sysrep_dir(REPO / "sysrep")
    checked = check_procedure(str(PROCEDURE), sysreps)
    for run_id, kinds in (("ended", [EventKind.RUN_STARTED, EventKind.RUN_COMPLETED]), ("refused", [])):
        host = TerminalHost(audit, binding="iva.yaml", onboard=True)
        view = OnboardView(
            run_id,
            checked.procedure,
            binding="iva.yaml",
            started_by="alice",
            mode="manual",
            sysreps=dict(checked.sysreps),
            host=host.hosting.host,
        )
        host.host_onboard(view, Habitat())
        for seq, kind in enumerate(kinds, 1):
            view.event(
                Event(run_id, seq, kind, "alice", None, {"procedure": "iva"} if seq == 1 else {}, datetime.now(UTC))
            )
        host.close()
        assert host.hosting.record(run_id) is None, run_id
