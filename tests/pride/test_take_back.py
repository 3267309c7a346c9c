"""A run that ends early takes back the Affordance Template instances it added, or says what it left.

The gateway here is an AT server in a dict (:class:`TemplateBench`, lowest free id per template, as
the real one): the executive sees the AT SysRep's commands and answers, nothing else. The real
stack's version of the first test is tests/interop/test_run_end.py.
"""

from __future__ import annotations

import io
import re
import time
from collections.abc import Callable, Mapping
from typing import Any

import pytest

from caretaker.terminal import LeftBehind, TerminalLines
from pride.events import Event, EventKind
from pride.executive import Executive, Hold, JournalFailure, Mode, OperatorActionError, RunStatus
from pride.leftovers import Holdings, Leftover, TakenBack
from pride.systems import CancelResult, CommandResult, LinkListener, LinkState, Outcome, TelemetryValue
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from support.audit import RecordedJournal
from support.executive_runs import TIMEOUT, Bench, finished, held
from support.procedures import FIXTURES

PROCEDURE = "at_add_plan_remove.xml"  # 1.1, 1.2 add; 2.1 plans; 3.1, 3.2 remove
AT = "affordance_templates"


class TemplateBench:
    """The AT SysRep's commands on instances kept in a set, named ``type:id`` with the lowest free id."""

    def __init__(self) -> None:
        self.instances: set[str] = set()
        self.sent: list[tuple[str, dict[str, Any]]] = []
        self.fail_next: dict[str, str] = {}  # command -> the message of its next (failed) answer
        self.lose_reply: set[str] = set()  # these execute, and their answer is lost (UNKNOWN)
        self.refuse_delete: dict[str, str] = {}  # instance -> why the server refuses to delete it
        self._link_listeners: list[LinkListener] = []

    def system_ids(self) -> frozenset[str]:
        return frozenset({AT})

    def robot(self) -> str:
        return "bench"

    def execute(self, sysrep_id: str, command_id: str, args: Mapping[str, Any], *, key: str | None = None) -> Any:
        self.sent.append((command_id, dict(args)))
        if command_id in self.fail_next:
            return CommandResult(Outcome.FAILED, self.fail_next.pop(command_id))
        name = str(args["affordance_template"])
        if command_id == "add_affordance_template":
            used = {int(n.split(":")[1]) for n in self.instances if n.split(":")[0] == name}
            number = min(set(range(len(used) + 1)) - used)
            self.instances.add(f"{name}:{number}")
            result = CommandResult(
                Outcome.SUCCEEDED, f"added {name}:{number}", {"id": number, "instance": f"{name}:{number}"}
            )
        elif command_id == "delete_affordance_template":
            if name in self.refuse_delete or name not in self.instances:
                return CommandResult(Outcome.FAILED, self.refuse_delete.get(name, f"no instance {name}"))
            self.instances.remove(name)
            result = CommandResult(Outcome.SUCCEEDED, f"deleted {name}", {"instance": name})
        else:
            result = CommandResult(Outcome.SUCCEEDED, "planned", {"instance": name})
        if command_id in self.lose_reply:
            return CommandResult(Outcome.UNKNOWN, "its answer was lost on the link")
        return result

    def cancel(self, key: str) -> CancelResult:
        return CancelResult(True, "nothing was moving")

    def one_way_delay(self) -> float:
        return 0.0

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        raise KeyError(item_id)  # the procedure reads none

    def add_listener(self, callback: Callable[..., None]) -> None:
        pass

    def add_link_listener(self, callback: LinkListener) -> None:
        self._link_listeners.append(callback)

    def lose_link(self) -> None:
        for listener in self._link_listeners:
            listener(LinkState("ws://bench:9090", False, time.time()))

    def close(self) -> None:
        pass


def _take_backs(journal: RecordedJournal, kind: EventKind) -> list[Event]:
    return [e for e in journal.events if e.kind is kind and e.data.to_json().get("take_back")]


def _stopped(journal: RecordedJournal) -> Event:
    """The run's RUN_STOPPED, which must be its last event (views and the habitat end a run there)."""
    assert journal.events[-1].kind is EventKind.RUN_STOPPED, journal.events[-1]
    return journal.events[-1]


def _resume(
    journal: RecordedJournal,
    gateway: TemplateBench,
    sysreps: dict[str, SysRep],
    new_journal: Callable[..., RecordedJournal],
) -> Executive:
    return Executive.resume(
        check_procedure(FIXTURES / PROCEDURE, sysreps),
        gateway,
        new_journal(journal.events),
        list(journal.events),
        "ben",
    )


def test_a_failed_run_stopped_removes_what_it_added_as_the_user_and_cannot_be_resumed(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    gateway = TemplateBench()
    gateway.fail_next["plan_trajectory"] = "no valid plan to grasp_and_pull"
    executive, _, journal = bench(Mode.AUTONOMOUS, PROCEDURE, gateway)
    executive.start("ana")
    held(executive, Hold.FAILURE, "2.1")
    assert gateway.instances == {"cdra_filter:0", "ready_pose:0"}

    executive.stop("ana", "unattended run needs an operator at 2.1")
    assert finished(executive).status is RunStatus.STOPPED
    assert gateway.instances == set()
    sent = _take_backs(journal, EventKind.COMMAND_SENT)
    assert [(e.actor, e.instruction, e.data.to_json()["command"], e.data.to_json()["args"]) for e in sent] == [
        ("ana", None, "delete_affordance_template", {"affordance_template": "cdra_filter:0", "id": 0}),
        ("ana", None, "delete_affordance_template", {"affordance_template": "ready_pose:0", "id": 0}),
    ]
    assert all(re.fullmatch(r"run-1/take-back/\d+", e.data.to_json()["key"]) for e in sent)
    assert len({e.data.to_json()["key"] for e in sent}) == 2  # each removal under a key of its own
    results = _take_backs(journal, EventKind.COMMAND_RESULT)
    assert [(e.actor, e.data.to_json()["outcome"], e.data.to_json()["message"]) for e in results] == [
        ("ana", "succeeded", "deleted cdra_filter:0"),
        ("ana", "succeeded", "deleted ready_pose:0"),
    ]
    stopped = _stopped(journal)
    assert (stopped.actor, stopped.data.to_json()["taken_back"]) == ("ana", ["cdra_filter:0", "ready_pose:0"])
    assert "left_behind" not in stopped.data.to_json()

    with pytest.raises(OperatorActionError, match=r"took back what it had added when it stopped \(cdra_filter:0, "):
        _resume(journal, gateway, sysreps, new_journal)


def test_a_removal_the_system_refuses_is_listed_with_its_words(bench: Bench) -> None:
    gateway = TemplateBench()
    gateway.fail_next["plan_trajectory"] = "no valid plan"
    gateway.refuse_delete["ready_pose:0"] = "ready_pose:0 is executing; wait for it to finish before deleting it"
    executive, _, journal = bench(Mode.AUTONOMOUS, PROCEDURE, gateway)
    executive.start("ana")
    held(executive, Hold.FAILURE, "2.1")
    executive.stop("ana", "giving up")
    assert gateway.instances == {"ready_pose:0"}
    stopped = _stopped(journal)
    assert stopped.data.to_json()["taken_back"] == ["cdra_filter:0"]
    why = "delete_affordance_template failed: ready_pose:0 is executing; wait for it to finish before deleting it"
    assert stopped.data.to_json()["left_behind"] == [{"system": AT, "name": "ready_pose:0", "why": why}]
    # the runner's terminal says it too, one line each
    out = io.StringIO()
    LeftBehind(TerminalLines(out))(stopped)
    assert out.getvalue() == f"LEFT ready_pose:0 on {AT}: {why}\n"


def _stopped_unremoved(
    bench: Bench, gateway: TemplateBench, hold: Hold, why: str, *, lose_link: bool = False
) -> RecordedJournal:
    """Run to ``hold`` at 2.1 (then lose the link) and stop: nothing is sent, both instances stay,
    listed for ``why``."""
    executive, _, journal = bench(Mode.AUTONOMOUS, PROCEDURE, gateway)
    executive.start("ana")
    held(executive, hold, "2.1")
    if lose_link:
        gateway.lose_link()
    executive.stop("ana", "end of shift")
    assert not _take_backs(journal, EventKind.COMMAND_SENT)
    assert gateway.instances == {"cdra_filter:0", "ready_pose:0"}
    assert _stopped(journal).data.to_json()["left_behind"] == [
        {"system": AT, "name": "cdra_filter:0", "why": why},
        {"system": AT, "name": "ready_pose:0", "why": why},
    ]
    return journal


def test_with_the_link_lost_nothing_is_sent_all_is_listed_and_a_resume_goes_on_with_it(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    gateway = TemplateBench()
    gateway.fail_next["plan_trajectory"] = "no valid plan"
    why = "not removed: the link to robot bench is lost"
    journal = _stopped_unremoved(bench, gateway, Hold.FAILURE, why, lose_link=True)
    resumed = _resume(journal, gateway, sysreps, new_journal)  # on a link that is up
    held(resumed, Hold.FAILURE, "2.1")
    resumed.stop("ben", "done with it")
    assert gateway.instances == set()


def test_with_an_outcome_unknown_nothing_is_sent_and_the_resume_that_learns_it_takes_back(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    gateway = TemplateBench()
    gateway.lose_reply.add("plan_trajectory")
    why = "not removed: the outcome of run-1/2.1/1 is not known"
    journal = _stopped_unremoved(bench, gateway, Hold.OUTCOME_UNKNOWN, why)
    resumed = _resume(journal, gateway, sysreps, new_journal)
    held(resumed, Hold.OUTCOME_UNKNOWN, "2.1")
    resumed.resolve("ben", "failed", "the server shows no plan")
    held(resumed, Hold.FAILURE, "2.1")
    resumed.stop("ben", "done with it")
    assert gateway.instances == set()


def test_a_completed_run_removes_nothing_itself_and_lists_what_its_procedure_left(bench: Bench) -> None:
    gateway = TemplateBench()
    executive, _, journal = bench(Mode.AUTONOMOUS, PROCEDURE, gateway)
    executive.set_breakpoint("ana", "3.2")
    executive.start("ana")
    held(executive, Hold.BREAKPOINT, "3.2")
    executive.skip("ana", "the next procedure uses the ready pose")
    assert finished(executive).status is RunStatus.COMPLETED
    assert gateway.instances == {"ready_pose:0"}
    assert not _take_backs(journal, EventKind.COMMAND_SENT)
    completed = journal.events[-1]
    assert completed.kind is EventKind.RUN_COMPLETED
    assert completed.data.to_json() == {
        "left_behind": [{"system": AT, "name": "ready_pose:0", "why": "the procedure completed without removing it"}]
    }


def test_a_run_whose_procedure_removes_its_templates_completes_as_before(bench: Bench) -> None:
    gateway = TemplateBench()
    executive, _, journal = bench(Mode.AUTONOMOUS, PROCEDURE, gateway)
    executive.start("ana")
    assert finished(executive).status is RunStatus.COMPLETED
    assert gateway.instances == set()
    assert (journal.events[-1].kind, journal.events[-1].data.to_json()) == (EventKind.RUN_COMPLETED, {})


def test_a_stop_that_keeps_them_for_a_resume_elsewhere_sends_nothing_and_lists_them(bench: Bench) -> None:
    gateway = TemplateBench()
    gateway.fail_next["plan_trajectory"] = "no valid plan"
    executive, _, journal = bench(Mode.AUTONOMOUS, PROCEDURE, gateway)
    executive.start("ana")
    held(executive, Hold.FAILURE, "2.1")
    executive.stop("web-server", "the web server shut down", take_back=False)
    assert gateway.instances == {"cdra_filter:0", "ready_pose:0"}
    assert [left["why"] for left in _stopped(journal).data.to_json()["left_behind"]] == [
        "kept for a resume of the run"
    ] * 2


def _result(seq: int, command: str, key: str, outcome: str, **values: Any) -> Event:
    data = {"system": AT, "command": command, "key": key, "args": {"affordance_template": "cdra_filter"}}
    success = None if outcome == "unknown" else outcome == "succeeded"
    return Event(
        "run-1",
        seq,
        EventKind.COMMAND_RESULT,
        "PAX",
        "1.1",
        {**data, "outcome": outcome, "success": success, "values": values},
    )


def test_an_add_of_unknown_outcome_is_listed_until_its_answer_names_what_it_added() -> None:
    holdings = Holdings()
    holdings.note(_result(1, "add_affordance_template", "run-1/1.1/1", "unknown"))
    unknown = "the outcome of run-1/1.1/1 is not known: it may have added something"
    assert holdings.left("x").left == (
        Leftover(AT, "add_affordance_template(affordance_template='cdra_filter')", unknown),
    )
    # asked again under the same key, the habitat answers what it did
    holdings.note(_result(2, "add_affordance_template", "run-1/1.1/1", "succeeded", id=0, instance="cdra_filter:0"))
    assert [(h.name, h.arguments) for h in holdings.held()] == [
        ("cdra_filter:0", {"affordance_template": "cdra_filter:0", "id": 0})
    ]
    assert holdings.unsure() == []
    holdings.note(_result(3, "delete_affordance_template", "run-1/3.1/1", "succeeded", instance="cdra_filter:0"))
    assert holdings.held() == [] and holdings.left("x") == TakenBack()


def test_an_add_an_operator_resolved_is_listed_as_unnamed_or_forgotten() -> None:
    holdings = Holdings()
    holdings.note(_result(1, "add_affordance_template", "run-1/1.1/1", "unknown"))
    holdings.note(_result(2, "add_affordance_template", "run-1/1.1/2", "unknown"))
    resolved = {"key": "run-1/1.1/1", "outcome": "succeeded", "reason": "it shows in RViz"}
    holdings.note(Event("run-1", 3, EventKind.OUTCOME_RESOLVED, "ana", "1.1", resolved))
    holdings.note(
        Event(
            "run-1",
            4,
            EventKind.OUTCOME_RESOLVED,
            "ana",
            "1.1",
            {**resolved, "key": "run-1/1.1/2", "outcome": "failed"},
        )
    )
    (left,) = holdings.unsure()
    assert left.why == "recorded as succeeded by ana, so its name is not known: check the system"


def test_a_stop_waiting_for_the_command_in_flight_ends_when_the_journal_fails_meanwhile(bench: Bench) -> None:
    executive, gateway, journal = bench()  # the lab bench: its vent (2.1) waits until cancelled
    gateway.block.add("vent")
    executive.start("lena")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("lena", "dock")
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.confirm("lena")
    assert executive.wait_for(lambda s: s.executing and s.current == "2.1", TIMEOUT)
    # the vent reached the system (so its command_sent is in the journal) and waits there
    assert gateway.blocking.wait(TIMEOUT), "the vent never reached the lab"
    journal.fail_with = RuntimeError("the database is gone")  # the vent's halted answer cannot be recorded
    with pytest.raises(JournalFailure, match="the database is gone"):
        executive.stop("lena", "end of shift")
    assert finished(executive).status is RunStatus.STOPPED
    assert EventKind.RUN_STOPPED not in journal.kinds()
