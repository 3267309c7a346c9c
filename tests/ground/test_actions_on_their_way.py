"""An action on a far run: on its way until its answer is due, unknown after, its late answer shown.

The waits derive from the link's light time (:class:`onboard.downlink.ActionTiming`), not
constants. Forwarding runs on real databases (a SQLite file, the session's PostgreSQL as the
runner role) with real change feeds; the host's performer is the test's: it says the action went
up and answers when the test lets it (the habitat across the link: tests/flight).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from ground.action_requests import ActionRequests, Answer, ForwardedAction
from ground.change_feed import ChangeNotice, open_change_feed
from onboard.downlink import ActionTiming
from records.audit_log import AuditLog
from rosbridge_wire.light_time import LightTime


def test_an_actions_answer_is_due_a_round_trip_and_its_work_after_it_was_sent() -> None:
    mars = ActionTiming.of(LightTime(600.0), sent=1000.0)
    assert mars == ActionTiming(sent=1000.0, expected_at=2210.0, expires_at=2260.0, gives_up_at=3470.0)
    moon = ActionTiming.of(LightTime(1.3), sent=0.0)
    assert (moon.expected_at, moon.expires_at) == pytest.approx((12.6, 62.6))


class FarHost:
    """A host whose answer comes from far away: says when it is due, answers when released."""

    def __init__(self, audit: AuditLog, due_in: float, none_after: float) -> None:
        self.due_in, self.none_after = due_in, none_after
        self.released = threading.Event()
        self.requests = ActionRequests(audit.engine, host_id="runner", console="runner", perform=self._perform)

    def _perform(self, request: ForwardedAction) -> Answer:
        now = time.time()
        request.on_its_way(now + self.due_in, now + self.none_after)
        assert self.released.wait(30), "the test never let the habitat answer"
        return Answer(200, {"ok": True, "result": f"on the habitat: {request.action['action']} by {request.user}"})


class Console(ActionRequests):
    """A console asking the far host, which hears (as any console does) when a request is answered."""

    def __init__(self, audit: AuditLog) -> None:
        super().__init__(audit.engine, host_id="console", console="console", perform=_never)
        self.answered = threading.Event()

    def notice(self, notice: ChangeNotice) -> None:
        super().notice(notice)
        if notice.channel == "actions" and notice.payload.startswith("done "):
            self.answered.set()


@pytest.fixture
def sides(audit: AuditLog) -> Iterator[tuple[FarHost, Console]]:
    """A far host, its lengths set by each test, and a console asking it."""
    host = FarHost(audit, 0.0, 0.0)
    asker = Console(audit)
    feed = open_change_feed(audit.engine)
    for side in (host.requests, asker):
        feed.subscribe(side.notice)
    assert feed.connected.wait(10)
    yield host, asker
    host.released.set()
    feed.close()
    host.requests.close()
    asker.close()


def _never(request: ForwardedAction) -> Answer:
    raise AssertionError(f"nothing is hosted on the console: {request}")


def _answered(asker: Console, request: int) -> dict[str, object] | None:
    """What the console knows of ``request`` once the host answered it (on the host's thread)."""
    assert asker.answered.wait(30), f"request {request} never answered"
    return asker.progress(request, "run-far")


def test_an_action_due_after_the_consoles_patience_is_on_its_way_at_once_then_answered(
    sides: tuple[FarHost, Console],
) -> None:
    host, asker = sides
    host.due_in, host.none_after = 1210.0, 2470.0  # 600 s one way
    answer = asker.forward("run-far", "runner", "alice", {"action": "halt"}, answer_within=30.0)
    assert answer.status == 202, answer
    known = answer.body["result"]
    assert known["state"] == "on_its_way" and not known["final"] and known["action"] == "halt"
    assert known["expected_at"] - time.time() > 1000  # the ground's clock time its answer is due
    assert asker.progress(known["request"], "run-far") == known | {"state": "on_its_way"}
    assert asker.progress(known["request"], "another-run") is None
    host.released.set()
    assert _answered(asker, known["request"]) == {
        "request": known["request"],
        "action": "halt",
        "state": "done",
        "final": True,
        "result": "on the habitat: halt by alice",
    }


def test_an_action_not_answered_when_due_is_unknown_and_its_late_answer_is_still_shown(
    sides: tuple[FarHost, Console],
) -> None:
    host, asker = sides
    host.due_in, host.none_after = 0.5, 60.0
    answer = asker.forward("run-far", "runner", "alice", {"action": "pause"}, answer_within=30.0)
    assert answer.status == 202, answer
    known = answer.body["result"]
    assert known["state"] == "unknown" and not known["final"]  # due, none came: it may still come
    host.released.set()
    answered = _answered(asker, known["request"])
    assert answered is not None and answered["result"] == "on the habitat: pause by alice"


def test_an_action_answered_before_it_is_due_is_answered_as_from_any_host(
    sides: tuple[FarHost, Console],
) -> None:
    host, asker = sides
    host.due_in, host.none_after = 12.6, 75.0  # the Moon
    host.released.set()
    answer = asker.forward("run-far", "runner", "alice", {"action": "continue"}, answer_within=30.0)
    assert answer == Answer(200, {"ok": True, "result": "on the habitat: continue by alice"})


def test_an_action_none_can_answer_any_more_is_finally_unknown(sides: tuple[FarHost, Console]) -> None:
    host, asker = sides
    host.due_in, host.none_after = -2.0, -1.0  # the host stopped listening before it answered
    answer = asker.forward("run-far", "runner", "alice", {"action": "stop"}, answer_within=30.0)
    assert answer.status == 202 and answer.body["result"]["state"] == "unknown" and answer.body["result"]["final"]
