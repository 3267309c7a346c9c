"""An onboard run through an outage: all traffic held for 10 minutes from the start of the pull-out.

The clean filter's id (4.1, a record) is not given at uplink. During the outage the habitat does
everything automatable up to it, each motion once (counted on the habitat), and holds there for
an operator; the ground says since when it has no news, catches up after the outage with the
habitat's chain hash for hash, learns that the run waits for an operator at 4.1, and (nobody at
its terminal) stops it, as an unattended ground run stops. How a flight is set up: flight_support.py.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import pytest

from records.audit_chain import utc

from .flight_support import DELAY, PULL_OUT, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=720), pytest.mark.timeout(1200)]


#: The issue's outage: far longer than the ground client's keepalive (its connection is dropped
#: and made again, many times), the bridge's ping timeout, and the onboard run's way to the record.
OUTAGE_S = 600.0


def test_an_outage_from_the_pull_out_the_habitat_goes_on_alone_to_the_record_and_the_ground_catches_up(
    ros_env: dict[str, str],
) -> None:
    with flight(ros_env, delay=DELAY, time_scale="0", onboard=True) as f:  # the motions at full speed
        run = f.run("--onboard", record=False)
        f.await_execution(PULL_OUT)
        f.link.control.hold(OUTAGE_S)
        held_at = datetime.now(UTC)
        silent = run.wait_for_line(r"no news from the habitat since", 120)
        waits = run.wait_for_line(r"the onboard run waits for an operator: 4\.1: ", OUTAGE_S + 300)
        run_id, status = result_of(run, 120)
        caught_up = run.wait_for_line(r"the habitat answers again; catching up from event \d+", 5)
        assert status == "stopped"
        habitat = f.habitat.onboard_chain(run_id)
        # on the habitat, while the link was held: everything up to the record, then the hold
        awaiting = next(e for e in habitat if e.kind == "awaiting_operator" and e.instruction == "4.1")
        assert utc(awaiting.time) < held_at + timedelta(seconds=OUTAGE_S), (awaiting.time, held_at)
        after = [e for e in habitat if e.seq > awaiting.seq]
        acted = [e for e in after if e.kind in ("instruction_started", "command_sent")]
        # nothing past it but the stop's take-back of the templates the run added, once stopped
        assert all(e.kind == "command_sent" and "/take-back/" in json.loads(e.data)["key"] for e in acted), acted
        stopped = habitat[-1]
        assert stopped.kind == "run_stopped" and "unattended run needs an operator at 4.1" in stopped.data
        assert len(json.loads(stopped.data).get("taken_back", [])) == len(acted), stopped.data
        # every command up to the hold executed once, and succeeded; every motion done once
        records = f.habitat.ledger_records()
        assert records and {r["state"] for r in records} == {"SUCCEEDED"}, records
        assert len({r["command_key"] for r in records}) == len(records)
        goals = f.goals()
        assert goals and len({goal for goal, _ in goals}) == len(goals) and {s for _, s in goals} == {4}, goals
        print(f"{len(goals)} arm motions on the habitat during the outage, each once")
        sent = [e for e in habitat if e.kind == "command_sent"]
        assert len(sent) == len(records), "a command logged on the habitat that the ledger did not execute, or twice"
        ground = f.ground_chain(run_id)
        assert [(e.seq, e.hash) for e in ground] == [(e.seq, e.hash) for e in habitat], "caught up, not the same"
        assert f.link.control.stats().holds == 1
        print(f"{silent.strip()} / {caught_up.strip()} / {waits.strip()}")
