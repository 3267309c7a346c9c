"""Part of a procedure: a run that starts at a step and stops after one (pride/run_section.py).

On the lab bench (its gateway a double: a unit test of the executive). ``lab_all_kinds.xml``'s
step ``finish`` reads ``${target}``, which only step 1's record binds: a start there needs it.
"""

from __future__ import annotations

import pytest

from pride.events import EventKind
from pride.executive import InstructionStatus, Mode, RunStatus
from pride.replay import replay
from pride.run_section import RunSection, SectionError
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from support.executive_runs import Bench, finished
from support.procedures import FIXTURES


def test_a_start_at_a_step_is_refused_with_what_the_skipped_steps_would_have_bound(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.AUTONOMOUS)
    with pytest.raises(SectionError) as refused:
        executive.start("alice", section=RunSection("finish"))
    said = str(refused.value)
    assert said.startswith("--from finish: the steps it skips would have bound target (read at ")
    assert "lab_all_kinds.xml:37:9" in said and said.endswith("give it with --set NAME=VALUE"), said
    assert journal.events == [] and gateway.sent == []  # nothing recorded, nothing sent
    with pytest.raises(SectionError, match=r"no step .finsh. \(steps: prepare, inspect, recover, finish, done, "):
        executive.start("alice", section=RunSection("finsh"))
    with pytest.raises(SectionError, match=r"--to prepare is step 1, before --from finish \(step 4\)"):
        executive.start("alice", section=RunSection("finish", "prepare", {"target": "dock"}))


def test_a_run_from_a_step_to_a_step_performs_only_that_part_and_says_so(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.AUTONOMOUS)
    executive.start("alice", section=RunSection("finish", "finish", {"target": "dock"}))
    snap = finished(executive)
    assert snap.status is RunStatus.COMPLETED
    assert [c for _, c, _ in gateway.sent] == ["count"]  # the sub-procedure's; not step 5's move
    started = journal.events[0]
    assert started.kind is EventKind.RUN_STARTED
    assert started.data.to_json()["section"] == {"from": "finish", "to": "finish", "given": {"target": "dock"}}
    assert snap.statuses["1.1"] is InstructionStatus.PENDING and snap.statuses["5.1"] is InstructionStatus.PENDING
    assert snap.statuses["4.2"] is InstructionStatus.COMPLETED  # read ${target} as given
    first = next(e for e in journal.events if e.kind is EventKind.INSTRUCTION_STARTED)
    assert first.instruction == "4.1"


def test_a_replay_of_a_run_of_part_starts_where_it_started(bench: Bench, sysreps: dict[str, SysRep]) -> None:
    executive, _, journal = bench(Mode.AUTONOMOUS)
    executive.start("alice", section=RunSection("finish", "finish", {"target": "dock"}))
    finished(executive)
    checked = check_procedure(FIXTURES / "lab_all_kinds.xml", sysreps)
    state = replay(checked.procedure, journal.events[:1], checked.load, mode=Mode.AUTONOMOUS, statuses={})
    assert state.frames[0].number() == "4.1" and state.frames[0].env == {"target": "dock"}
    assert state.stops_after == 4
