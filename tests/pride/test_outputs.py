"""Sub-procedures that hand values back: ``<output>``, ``<set>`` and ``<call result=...>``.

The lab bench (its gateway a double: a unit test of the executive) runs ``lab_outputs.xml``, which
calls ``lab_locate.xml`` twice, the second time with the first call's output, and moves the arm to
where the second call says. Lint's errors for outputs are in test_lint.py (fixtures/broken).
"""

from __future__ import annotations

from pride.events import EventKind
from pride.executive import InstructionStatus, Mode, RunStatus
from pride.phrasing import phrase, raw_form
from pride.replay import replay
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from support.executive_runs import Bench, finished
from support.procedures import FIXTURES


def test_a_caller_reads_the_outputs_its_sub_procedure_set(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.AUTONOMOUS, "lab_outputs.xml")
    executive.start("alice")
    snap = finished(executive)

    assert snap.status is RunStatus.COMPLETED
    assert [(c, a) for _, c, a in gateway.sent] == [
        ("count", {"n": 2}),
        ("count", {"n": 4}),  # the first call's output, typed as the callee's input
        ("move", {"target": "dock", "speed": 0.5}),
    ]
    returned = [(e.instruction, e.data.to_json()) for e in journal.events if e.kind is EventKind.CALL_RETURNED]
    assert returned == [
        ("1.1", {"procedure": "lab_locate", "result": "first", "outputs": {"total": 4, "where": "dock"}}),
        ("1.2", {"procedure": "lab_locate", "result": "second", "outputs": {"total": 8, "where": "dock"}}),
    ]
    set_in_second = [(e.instruction, e.data.to_json()) for e in journal.events if e.kind is EventKind.VALUE_SET][2:]
    assert set_in_second == [
        ("1.2/2.1", {"name": "total", "value": 8}),
        ("1.2/2.2", {"name": "where", "value": "dock"}),
    ]
    assert snap.statuses["2.1"] is InstructionStatus.COMPLETED  # the branch read ${second.total} as 8
    assert snap.statuses["3.1"] is InstructionStatus.PENDING


def test_a_resumed_run_knows_what_the_calls_before_it_returned(bench: Bench, sysreps: dict[str, SysRep]) -> None:
    """Replay (what a resume and the onboard catch-up rebuild from the log) puts the outputs back."""
    executive, _, journal = bench(Mode.AUTONOMOUS, "lab_outputs.xml")
    executive.start("alice")
    finished(executive)
    checked = check_procedure(FIXTURES / "lab_outputs.xml", sysreps)
    events = list(journal.events)
    before_move = next(
        n for n, e in enumerate(events) if e.kind is EventKind.INSTRUCTION_STARTED and e.instruction == "1.3"
    )
    state = replay(checked.procedure, events[:before_move], checked.load, mode=Mode.AUTONOMOUS, statuses={})
    assert [f.prefix for f in state.frames] == [""]
    assert state.frames[0].env == {"first": {"total": 4, "where": "dock"}, "second": {"total": 8, "where": "dock"}}
    inside = next(n for n, e in enumerate(events) if e.kind is EventKind.VALUE_SET and e.instruction == "1.2/2.2")
    state = replay(checked.procedure, events[: inside + 1], checked.load, mode=Mode.AUTONOMOUS, statuses={})
    assert [f.prefix for f in state.frames] == ["", "1.2/"]
    assert state.frames[1].env["total"] == 8 and state.frames[1].env["where"] == "dock"


def test_a_set_and_a_call_that_names_its_result_read_as_words(sysreps: dict[str, SysRep]) -> None:
    callee = check_procedure(FIXTURES / "lab_locate.xml", sysreps).procedure
    set_total = callee.instruction("2.1")
    assert set_total is not None
    assert str(phrase(set_total, sysreps, callee)) == "Set total to ${counted.total}"
    assert raw_form(set_total) == "set total = ${counted.total}"
    caller = check_procedure(FIXTURES / "lab_outputs.xml", sysreps).procedure
    call = caller.instruction("1.2")
    assert call is not None
    assert raw_form(call) == "second = call lab_locate.xml(n=${first.total})"
