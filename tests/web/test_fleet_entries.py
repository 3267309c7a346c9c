"""The fleet's order (console/fleet.py): what needs an operator first, then what may soon, idle robots last.

The views are as hosts publish them in ``run_hosts`` (a console's live run, a supervisor's onboard
run); the browser test of the fleet view is test_fleet_view.py.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from console.fleet import URGENCY, fleet_entries
from ground.run_hosts import HostRecord

T0 = datetime(2026, 12, 7, 4, 0, tzinfo=UTC)


def hosted(run_id: str, binding: str, *, alive: bool = True, **state: Any) -> tuple[HostRecord, dict[str, Any]]:
    record = HostRecord(run_id, "h1", "console-1", binding, "alice", T0, T0, "active", "autonomous", alive)
    telemetry = state.pop("telemetry", {"readings": []})
    return record, {"state": {"procedure": "p", "current": "1.1", **state}, "telemetry": telemetry}


ROBOTS = {name: (f"{name}.yaml",) for name in ("a", "b", "c", "d", "e", "f", "g")}


def test_holds_then_lost_hosts_then_silent_links_then_limits_then_running_then_idle() -> None:
    red = {"readings": [{"system": "cdra", "item": "co2", "limit": {"state": "red", "words": "RED HIGH"}}]}
    entries = fleet_entries(
        ROBOTS,
        [
            hosted("r-a", "a.yaml"),
            hosted("r-b", "b.yaml", telemetry=red),
            hosted("r-c", "c.yaml", link={"state": "silent", "since": "2026-12-07T04:01:00+00:00"}, onboard={}),
            hosted("r-d", "d.yaml", alive=False),
            hosted("r-e", "e.yaml", hold="halted", reason="by bob: the arm came too close"),
            hosted("r-f", "f.yaml", awaiting="manual", arrived="2026-12-07T04:02:00+00:00"),
        ],
    )
    assert [(e.robot, e.state) for e in entries] == [
        ("e", "holds for an operator"),
        ("f", "holds for an operator"),
        ("d", "host lost"),
        ("c", "link silent"),
        ("b", "limits out"),
        ("a", "running"),
        ("g", "idle"),
    ]
    assert entries[0].needs == "halted: by bob: the arm came too close"
    assert entries[1].needs == "manual"
    assert entries[3].link == "silent since 2026-12-07T04:01:00+00:00" and entries[3].onboard
    assert entries[4].limits_out == ("cdra.co2 RED HIGH",)
    assert entries[6].run_id == "" and entries[6].urgency == len(URGENCY) - 1


def test_among_holds_the_longest_waiting_is_first_and_an_approval_says_so() -> None:
    entries = fleet_entries(
        ROBOTS,
        [
            hosted("r-a", "a.yaml", awaiting="operator", arrived="2026-12-07T04:05:00+00:00"),
            hosted("r-b", "b.yaml", hold="approval", approval={"number": "1.2"}, arrived="2026-12-07T04:03:00+00:00"),
        ],
    )
    assert [(e.robot, e.needs) for e in entries[:2]] == [("b", "a second operator's approval"), ("a", "operator")]


def test_a_run_on_a_binding_the_console_does_not_list_is_shown_under_its_robot() -> None:
    [entry] = fleet_entries({}, [hosted("r-x", "far.yaml", robot="far-robot")])
    assert (entry.robot, entry.bindings, entry.state) == ("far-robot", ("far.yaml",), "running")
