"""Typed events keep the JSON, and so the hashes, of every run stored before them.

``fixtures/stored_runs_every_kind.json`` holds fifteen runs of the lab bench as the audit log
stored them before events were typed (every field the chain covers, with its hash), and two logs
of refused acts added with that kind (a refused start under its own id; a self-approval and an
observer's act): together they record every event kind and every shape of data a kind takes
(optional keys present and absent). A run of ``lab_outputs.xml`` adds the outputs a
sub-procedure sets and hands back (``value_set``, ``call_returned``), a run of part of a
procedure the ``section`` its start records, and two attaches to an onboard run, each under an id
of its own, the ``supervisor_attached`` of one and the refusal of the other.
Read back into payloads and stored again through the real audit log, each event must get the same
data text and the same hash; made afresh from its fields (as an emitter makes it), the same JSON.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import textwrap
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest

from pride.event_json import EventDataError
from pride.event_payloads import LinkLost, RunStopped, payload_from_json
from pride.events import Event, EventKind
from records.audit_log import AuditLog
from support.procedures import FIXTURES, REPO

STORED = FIXTURES / "stored_runs_every_kind.json"


def _rows() -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = json.loads(STORED.read_text(encoding="utf-8"))
    return rows


def _event(row: dict[str, Any]) -> Event:
    kind = EventKind(row["kind"])
    data = payload_from_json(kind, json.loads(row["data"]))
    return Event(
        row["run_id"], row["seq"], kind, row["actor"], row["instruction"], data, datetime.fromisoformat(row["time"])
    )


def test_the_stored_runs_record_every_kind() -> None:
    assert {row["kind"] for row in _rows()} == {kind.value for kind in EventKind}


def test_stored_again_every_event_gets_its_stored_data_and_hash(tmp_path: Path) -> None:
    audit = AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")
    try:
        rows = _rows()
        for row in rows:
            audit.append(_event(row))
        for run_id in sorted({row["run_id"] for row in rows}):
            expected = [(r["seq"], r["data"], r["prev_hash"], r["hash"]) for r in rows if r["run_id"] == run_id]
            stored = [(e.seq, e.data, e.prev_hash, e.hash) for e in audit.stored_events(run_id)]
            assert stored == expected, run_id
            assert audit.verify(run_id).ok
    finally:
        audit.close()


def test_a_payload_made_from_its_fields_writes_the_stored_json() -> None:
    """What an emitter makes today is what was stored before: optional keys left out as they were."""
    for row in _rows():
        read = payload_from_json(EventKind(row["kind"]), json.loads(row["data"]))
        made = dataclasses.replace(read, stored=None)
        assert made.to_json() == json.loads(row["data"]), row


def test_an_older_runs_keys_are_kept_and_a_missing_field_reads_empty() -> None:
    """LINK_LOST as once documented (``link``, no ``links`` nor ``quiet``): read, and written back as it was."""
    old = {"link": "ws://lab.bench:9090", "since": "2026-11-01T10:00:00+00:00", "in_flight": 1}
    read = payload_from_json(EventKind.LINK_LOST, old)
    assert isinstance(read, LinkLost)
    assert (read.links, read.quiet, read.in_flight, read.extra) == ((), False, 1, {"link": "ws://lab.bench:9090"})
    assert read.to_json() == old
    for row in _rows():
        data = {**json.loads(row["data"]), "added_by_a_newer_version": {"nested": [1, 2]}}
        again = payload_from_json(EventKind(row["kind"]), data).to_json()
        assert json.dumps(again, sort_keys=True) == json.dumps(data, sort_keys=True)


@pytest.mark.parametrize(
    ("kind", "data", "says"),
    [
        (EventKind.RUN_STOPPED, {"reason": 3, "key": None, "cancel": None}, "run_stopped: data.reason must be text"),
        (EventKind.LINK_LOST, {"links": ["a", 2], "since": "", "in_flight": 0}, "data.links must be a list of text"),
        (EventKind.LINK_LOST, {"links": [], "since": "", "in_flight": True}, "data.in_flight must be an integer"),
        (EventKind.COMMAND_RESULT, {"success": "yes"}, "data.success must be true or false or null"),
        (EventKind.PAUSED, ["not", "an", "object"], "paused: data must be an object, not list"),
    ],
)
def test_hostile_data_is_refused_saying_which_field_and_type(kind: EventKind, data: Any, says: str) -> None:
    with pytest.raises(EventDataError, match=says.replace(".", r"\.")):
        payload_from_json(kind, data)


def test_an_event_carries_only_its_kinds_payload() -> None:
    stopped = RunStopped(reason="", key=None, cancel=None)
    with pytest.raises(ValueError, match="a halt event cannot carry RunStopped"):
        Event("run-1", 1, EventKind.HALT, "ana", None, stopped)
    assert Event.of("run-1", 1, "ana", None, stopped).kind is EventKind.RUN_STOPPED


_FOLD = """
    from typing import assert_never

    from pride.event_payloads import Payload, {names}


    def fold(data: Payload) -> str:
        match data:
            case {cases}:
                return type(data).__name__
            case _:
                assert_never(data)
"""


def _check_fold(tmp_path: Path, names: list[str]) -> subprocess.CompletedProcess[str]:
    source = tmp_path / "fold.py"
    source.write_text(textwrap.dedent(_FOLD.format(names=", ".join(names), cases=" | ".join(f"{n}()" for n in names))))
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--follow-imports=silent", "--no-incremental", str(source)],
        cwd=tmp_path,
        env={"MYPYPATH": str(REPO / "python"), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=False,
    )


def test_a_fold_that_forgets_a_kind_fails_mypy(tmp_path: Path) -> None:
    from pride import event_payloads

    names = sorted(cls.__name__ for cls in event_payloads._BY_KIND.values())
    assert _check_fold(tmp_path, names).returncode == 0
    missing = _check_fold(tmp_path, [n for n in names if n != "LinkRestored"])
    assert missing.returncode == 1
    assert 'Argument 1 to "assert_never" has incompatible type "LinkRestored"' in missing.stdout, missing.stdout
