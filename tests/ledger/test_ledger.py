"""The command ledger as a real process with a real ROS service behind it: each key executes at
most once (counted by the service itself), re-sends get the recorded outcome or join the call,
a restart turns interrupted calls into UNKNOWN, and a foreign epoch is never executed."""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

from support.processes import ManagedProcess

from .ledger_support import LedgerClient

pytestmark = pytest.mark.ros

COUNT, REFUSE, HOLD, SET = "/ledger_test/count", "/ledger_test/refuse", "/ledger_test/hold", "/ledger_test/set"


StartLedger = Callable[[Path], tuple[ManagedProcess, str]]


@pytest.fixture
def start_ledger(launch: Callable[..., ManagedProcess]) -> StartLedger:
    """Start ``caretaker ledger --state-dir DIR``: the process and its epoch (from its READY line)."""

    def start(state_dir: Path) -> tuple[ManagedProcess, str]:
        process = launch("ledger", "--state-dir", str(state_dir), "--default-timeout", "30")
        return process, process.wait_ready().split()[2]

    return start


def test_a_duplicate_key_executes_once(start_ledger: StartLedger, client: LedgerClient, tmp_path: Path) -> None:
    _, epoch = start_ledger(tmp_path)
    before = client.counts().get("count", 0)
    first = client.execute("run-a/1.1/1", COUNT)
    assert (first.state, first.epoch) == ("SUCCEEDED", epoch), first.message
    assert json.loads(first.response_json) == {"success": True, "message": f"count {before + 1}"}
    again = client.execute("run-a/1.1/1", COUNT, epoch=epoch)
    assert again.state == "SUCCEEDED" and again.response_json == first.response_json
    assert again.message.startswith("recorded outcome")
    assert client.counts()["count"] == before + 1
    retried = client.execute("run-a/1.1/2", COUNT)  # a new attempt is a new command
    assert retried.state == "SUCCEEDED" and client.counts()["count"] == before + 2
    assert client.outcome("run-a/1.1/1").state == "SUCCEEDED"
    assert client.outcome("run-a/9.9/1").state == "NOT_FOUND"


def test_an_answer_of_failure_is_failed_and_recorded(
    start_ledger: StartLedger, client: LedgerClient, tmp_path: Path
) -> None:
    _, epoch = start_ledger(tmp_path)
    before = client.counts().get("refuse", 0)
    failed = client.execute("run-b/2.1/1", REFUSE, type_="std_srvs/srv/Trigger")
    assert failed.state == "FAILED" and failed.message == "refused by the peer"
    assert client.execute("run-b/2.1/1", REFUSE, epoch=epoch).state == "FAILED"
    assert client.counts()["refuse"] == before + 1


def test_a_resend_during_the_call_joins_it(
    start_ledger: StartLedger, client: LedgerClient, peer: ManagedProcess, tmp_path: Path
) -> None:
    ledger, epoch = start_ledger(tmp_path)
    before = client.counts().get("hold", 0)
    first = client.execute_async("run-c/3.1/1", HOLD)
    peer.wait_for_line(rf"^CALLED hold {before + 1}$", 30)
    resent = client.execute_async("run-c/3.1/1", HOLD, epoch=epoch)
    ledger.wait_for_line(r"run-c/3\.1/1: re-sent while in progress: joining the call", 30)
    assert client.outcome("run-c/3.1/1").state == "IN_PROGRESS"
    client.release()
    answers = [_result(future) for future in (first, resent)]
    assert [a.state for a in answers] == ["SUCCEEDED", "SUCCEEDED"]
    assert answers[0].response_json == answers[1].response_json
    assert client.counts()["hold"] == before + 1


def test_bad_requests_get_clear_answers_and_execute_nothing(
    start_ledger: StartLedger, client: LedgerClient, tmp_path: Path
) -> None:
    start_ledger(tmp_path)
    before = client.counts()
    cases = [
        (dict(key="run-d/1/1", service=SET, request_json="{not json"), "request_json is not JSON"),
        (dict(key="run-d/2/1", service=SET, request_json="[1]"), "must be a JSON object"),
        (dict(key="run-d/3/1", service=SET, request_json='{"data": "yes"}'), "does not fit std_srvs/srv/SetBool"),
        (dict(key="run-d/4/1", service=SET, type_="std_srvs/srv/Nope"), "unknown srv type 'std_srvs/srv/Nope'"),
        (dict(key="run-d/5/1", service=SET, type_="std_srvs/srv/Trigger"), "has type std_srvs/srv/SetBool"),
        (dict(key="run-d/6/1", service="/ledger_test/absent"), "service /ledger_test/absent does not exist"),
        (dict(key="run-d/9/1", service="not a name", type_="std_srvs/srv/Trigger"), "Invalid service name"),
        (dict(key="no-slashes", service=COUNT), "command_key must be '<run_id>/<instruction>/<attempt>'"),
        (dict(key="run-d/7/1", service=COUNT, timeout=-1.0), "timeout must be 0"),
    ]
    for case, expected in cases:
        answer = client.execute(case.pop("key"), case.pop("service"), **case)
        assert answer.state == "REFUSED" and expected in answer.message, (expected, answer)
    assert client.counts() == before
    assert client.outcome("run-d/1/1").state == "REFUSED"  # recorded: a re-send gets the same answer
    good = client.execute("run-d/8/1", SET, request_json='{"data": true}')
    assert good.state == "SUCCEEDED" and json.loads(good.response_json)["message"] == "set true"
    reused = client.execute("run-d/8/1", SET, request_json='{"data": false}')
    assert reused.state == "REFUSED" and "already names another call" in reused.message


def test_no_answer_in_time_is_unknown_until_the_answer_comes(
    start_ledger: StartLedger, client: LedgerClient, peer: ManagedProcess, tmp_path: Path
) -> None:
    ledger, epoch = start_ledger(tmp_path)
    before = client.counts().get("hold", 0)
    late = client.execute("run-e/1/1", HOLD, timeout=1.0)
    assert late.state == "UNKNOWN"
    assert "no answer from /ledger_test/hold within 1 s; it may have executed" in late.message
    assert client.execute("run-e/1/1", HOLD, epoch=epoch).state == "UNKNOWN"  # recorded, not run again
    client.release()
    ledger.wait_for_line(r"run-e/1/1: late answer recorded: SUCCEEDED", 30)
    assert client.outcome("run-e/1/1").state == "SUCCEEDED"
    assert client.counts()["hold"] == before + 1


def test_a_restarted_ledger_keeps_outcomes_and_marks_interrupted_calls_unknown(
    start_ledger: StartLedger, client: LedgerClient, peer: ManagedProcess, tmp_path: Path
) -> None:
    ledger, epoch = start_ledger(tmp_path)
    before = client.counts()
    finished = client.execute("run-f/1/1", COUNT)
    assert finished.state == "SUCCEEDED"
    client.execute_async("run-f/2/1", HOLD)
    peer.wait_for_line(rf"^CALLED hold {before.get('hold', 0) + 1}$", 30)
    ledger.kill()
    _, same_epoch = start_ledger(tmp_path)
    assert same_epoch == epoch  # the same memory
    interrupted = client.outcome("run-f/2/1")
    assert interrupted.state == "UNKNOWN" and "stopped while this call was in progress" in interrupted.message
    assert client.execute("run-f/2/1", HOLD, epoch=epoch).state == "UNKNOWN"
    kept = client.execute("run-f/1/1", COUNT, epoch=epoch)
    assert kept.state == "SUCCEEDED" and kept.response_json == finished.response_json
    client.release()  # the peer answers the dead ledger's call
    counts = client.counts()
    assert counts["count"] == before.get("count", 0) + 1 and counts["hold"] == before.get("hold", 0) + 1


def test_a_new_memory_has_a_new_epoch_and_never_runs_a_foreign_resend(
    start_ledger: StartLedger, client: LedgerClient, tmp_path: Path
) -> None:
    old_ledger, old_epoch = start_ledger(tmp_path / "old")
    assert client.execute("run-g/1/1", COUNT).state == "SUCCEEDED"
    old_ledger.stop()
    _, new_epoch = start_ledger(tmp_path / "new")
    assert new_epoch != old_epoch
    before = client.counts()["count"]
    foreign = client.execute("run-g/1/1", COUNT, epoch=old_epoch)
    assert foreign.state == "UNKNOWN" and foreign.epoch == new_epoch and "cannot be learnt" in foreign.message
    assert client.outcome("run-g/1/1").state == "NOT_FOUND"  # refused without a record
    assert client.execute("run-g/2/1", COUNT, epoch=new_epoch).state == "SUCCEEDED"  # first send lost, re-sent
    assert client.execute("run-g/3/1", COUNT).state == "SUCCEEDED"  # a first send
    assert client.counts()["count"] == before + 2


def test_a_damaged_state_file_is_refused_with_its_name(launch: Callable[..., ManagedProcess], tmp_path: Path) -> None:
    (tmp_path / "command_ledger.sqlite").write_text("this is not a database\n" * 100)
    process = launch("ledger", "--state-dir", str(tmp_path), wait=False)
    process.proc.wait(60)
    assert process.proc.returncode == 2
    assert "command_ledger.sqlite: cannot use it as the ledger's state" in process.tail()


def _result(future: object, timeout: float = 60.0) -> object:
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())  # type: ignore[attr-defined]
    assert done.wait(timeout), "no answer"
    return future.result()  # type: ignore[attr-defined]
