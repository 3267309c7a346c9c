"""Audit log: append rate and latency on SQLite and PostgreSQL, 1 and 4 concurrent runs; report time.

Each writer is its own process (as runners are) appending its own run's events through
:class:`records.audit_log.AuditLog` with full durability (SQLite WAL + ``synchronous=FULL``,
PostgreSQL ``synchronous_commit=on``, ``fsync=on``); the time of every ``append`` is what PAX
waits for an event. Back to back (every writer appending as fast as it can: the throughput)
and paced (``--paced-rate`` events per second per run, far more than a run emits: the latency
PAX sees in use). Peer, in the same processes and interleaved run by run: the bare commit, one
INSERT of the same row and COMMIT through the driver (sqlite3 / psycopg) with the same settings,
so the difference is what the audit log adds (hash chain, SQLAlchemy, retry bookkeeping).

The report time is for one run of ``--report-events`` events (default 100,000): reading the
run, checking its chain, and ``caretaker report`` end to end (a new process: start-up included).

PostgreSQL is a server of this script's own (tests/support/postgres.py: initdb in a temporary
directory, loopback only), the runner connecting as the ``pax`` role.

    .venv/bin/python bench/audit_log.py [--events 2000] [--report-events 100000]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, replace
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from pride.event_payloads import payload_from_json  # noqa: E402
from pride.events import PAX, Event, EventKind  # noqa: E402
from records.audit_chain import GENESIS, StoredEvent  # noqa: E402
from records.audit_log import AuditLog, database_url  # noqa: E402
from records.audit_schema import audit_records  # noqa: E402
from support.postgres import OWNER, RUNNER, postgres_server  # noqa: E402

_DATA = {
    "system": "ur10",
    "command": "execute_plan",
    "hazardous": False,
    "args": {"affordance_template": "cdra_filter:0", "trajectory": "grasp_and_pull", "steps": 12, "speed": 0.25},
}


def _event(run_id: str, seq: int) -> Event:
    kind = EventKind.RUN_STARTED if seq == 1 else EventKind.COMMAND_SENT
    data = payload_from_json(kind, {"procedure": "bench"} if seq == 1 else _DATA)
    return Event(run_id, seq, kind, PAX, None if seq == 1 else f"{seq // 40 + 1}.{seq % 40 + 1}", data)


_BARE_INSERT = (
    "INSERT INTO bare_records (run_id, seq, time, actor, kind, instruction, data) VALUES ({0},{0},{0},{0},{0},{0},{0})"
)


def _bare_commit(url: str) -> Callable[[Event], None]:
    """One INSERT + COMMIT through the driver itself, same durability as the audit log."""

    def values(event: Event) -> tuple[Any, ...]:
        return (
            event.run_id,
            event.seq,
            event.time.isoformat(),
            event.actor,
            event.kind.value,
            event.instruction,
            json.dumps(event.data.to_json(), sort_keys=True),
        )

    if url.startswith("sqlite"):
        lite = sqlite3.connect(url.removeprefix("sqlite:///"), isolation_level=None, timeout=10)
        lite.execute("PRAGMA journal_mode=WAL")
        lite.execute("PRAGMA synchronous=FULL")

        def commit_sqlite(event: Event) -> None:
            lite.execute("BEGIN")
            lite.execute(_BARE_INSERT.format("?"), values(event))
            lite.execute("COMMIT")

        return commit_sqlite

    import psycopg

    server = psycopg.connect(database_url(url).replace("postgresql+psycopg://", "postgresql://"), autocommit=True)

    def commit_postgresql(event: Event) -> None:  # autocommit: one round trip, as the audit log does
        server.execute(_BARE_INSERT.format("%s"), values(event))

    return commit_postgresql


_PATHS = ("audit", "peer", "paced")


def _writer(
    url: str, run_id: str, events: int, paced: tuple[int, float, float], barrier: Any
) -> dict[str, list[float]]:
    """One runner: its own connection, its own run; per-append seconds for each path in :data:`_PATHS`.

    ``audit`` and ``peer`` append back to back (throughput); ``paced`` appends ``paced[0]`` events
    at ``paced[1]`` per second starting ``paced[2]`` s late (runs are not in lock step), as a busy
    runner does, so its latency is what PAX waits in use.
    """
    log = AuditLog(url)
    bare = _bare_commit(url)
    times: dict[str, list[float]] = {path: [] for path in _PATHS}
    for path, append, count, interval in (
        ("audit", log.append, events, 0.0),
        ("peer", bare, events, 0.0),
        ("paced", log.append, paced[0], 1 / paced[1]),
    ):
        barrier.wait()  # every writer starts each phase together
        began_phase = time.perf_counter() + (paced[2] if interval else 0.0)
        for seq in range(1, count + 1):
            if interval:
                time.sleep(max(0.0, began_phase + seq * interval - time.perf_counter()))
            event = _event(f"{run_id}-{path}", seq)
            began = time.perf_counter()
            append(event)
            times[path].append(time.perf_counter() - began)
    barrier.wait()
    log.close()
    return times


def _writers(url: str, writers: int, events: int, paced: tuple[int, float]) -> dict[str, Any]:
    context = multiprocessing.get_context("spawn")
    with context.Manager() as manager, context.Pool(writers) as pool:
        barrier = manager.Barrier(writers + 1)
        pending = [
            pool.apply_async(_writer, (url, f"bench-{writers}-{n}", events, (*paced, n / writers / paced[1]), barrier))
            for n in range(writers)
        ]
        marks = []
        for _ in range(len(_PATHS) + 1):  # each phase's start, and the end
            barrier.wait(timeout=3600)
            marks.append(time.perf_counter())
        results = [p.get(timeout=3600) for p in pending]
    out: dict[str, Any] = {}
    for n, path in enumerate(_PATHS):
        times = sorted(t for r in results for t in r[path])
        out[path] = {
            "p50": statistics.median(times) * 1e3,
            "p95": times[int(len(times) * 0.95)] * 1e3,
            "p99": times[int(len(times) * 0.99)] * 1e3,
            "max": times[-1] * 1e3,
            "rate": len(times) / (marks[n + 1] - marks[n]),
        }
    return out


def _prepare_bare(url: str) -> None:
    log = AuditLog(url)
    log.close()
    if url.startswith("sqlite"):
        with sqlite3.connect(url.removeprefix("sqlite:///")) as connection:
            connection.execute(
                "CREATE TABLE bare_records (run_id TEXT, seq INTEGER, time TEXT, actor TEXT, kind TEXT, "
                "instruction TEXT, data TEXT, UNIQUE (run_id, seq))"
            )


def _long_run(url: str, count: int) -> str:
    """Store one run of ``count`` events (linked as the audit log links them) in bulk."""
    from sqlalchemy import create_engine, insert

    run_id = f"report-{count}"
    started = datetime.now(UTC)
    steps = [{"number": n, "id": f"s{n}", "title": f"Step {n}"} for n in range(1, 11)]
    kinds = [
        EventKind.INSTRUCTION_STARTED,
        EventKind.COMMAND_SENT,
        EventKind.COMMAND_RESULT,
        EventKind.TELEMETRY_SEEN,
        EventKind.INSTRUCTION_COMPLETED,
    ]
    engine = create_engine(database_url(url))
    prev, batch = GENESIS, []
    with engine.begin() as connection:
        for seq in range(1, count + 1):
            kind = EventKind.RUN_STARTED if seq == 1 else kinds[seq % len(kinds)]
            instruction = None if seq == 1 else f"{(seq * 10) // count + 1 if seq < count else 10}.{seq % 7 + 1}"
            data = (
                {"procedure": "bench", "title": "Bench", "version": "1", "mode": "autonomous", "steps": steps}
                if seq == 1
                else {**_DATA}
                if kind is EventKind.COMMAND_SENT
                else {"success": True, "message": "done", "values": {"arrived": True}}
                if kind is EventKind.COMMAND_RESULT
                else {"system": "ur10", "item": "joint_1", "value": 0.5, "condition": "< 1", "ok": True}
                if kind is EventKind.TELEMETRY_SEEN
                else {"next": instruction}
            )
            row = StoredEvent(
                run_id,
                seq,
                started + timedelta(milliseconds=seq),
                PAX,
                kind.value,
                instruction,
                json.dumps(data, sort_keys=True),
                prev,
            )
            row = replace(row, hash=row.expected_hash())
            prev = row.hash
            batch.append(asdict(row))
            if len(batch) == 5000:
                connection.execute(insert(audit_records), batch)
                batch = []
        if batch:
            connection.execute(insert(audit_records), batch)
    engine.dispose()
    return run_id


def _report_time(url: str, count: int) -> dict[str, float]:
    run_id = _long_run(url, count)
    log = AuditLog(url)
    began = time.perf_counter()
    events = log.events(run_id)
    read = time.perf_counter() - began
    began = time.perf_counter()
    check = log.verify(run_id)
    verify = time.perf_counter() - began
    assert check.ok and len(events) == count, check.describe()
    log.close()
    with tempfile.TemporaryDirectory() as out:
        began = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-m", "caretaker.cli", "report", run_id, "--db", url, "--out", out],
            capture_output=True,
            text=True,
            timeout=3600,
        )
        report = time.perf_counter() - began
        assert done.returncode == 0, done.stderr
    return {"read": read, "verify": verify, "report": report}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=2000, help="events each writer appends (default 2000)")
    parser.add_argument("--paced-events", type=int, default=300, help="events each writer appends paced")
    parser.add_argument("--paced-rate", type=float, default=20.0, help="events per second per paced writer")
    parser.add_argument("--report-events", type=int, default=100_000, help="events of the reported run")
    parser.add_argument(
        "--database",
        choices=("sqlite", "postgresql"),
        action="append",
        help="only these databases (repeatable; default both)",
    )
    args = parser.parse_args(argv)
    kinds = args.database or ["sqlite", "postgresql"]
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory(prefix="ct-bench-audit-") as tmp, postgres_server() as server:
        for kind in kinds:
            for writers in (1, 4):
                if kind == "sqlite":
                    url = f"sqlite:///{tmp}/audit-{writers}.db"
                    _prepare_bare(url)
                else:
                    name = server.new_database()
                    AuditLog(server.url(name, OWNER)).close()
                    server.sql(
                        "CREATE TABLE bare_records (run_id TEXT, seq INTEGER, time TEXT, actor TEXT, kind TEXT, "
                        "instruction TEXT, data TEXT, UNIQUE (run_id, seq)); "
                        f"GRANT SELECT, INSERT ON bare_records TO {RUNNER}",
                        database=name,
                        role=OWNER,
                    )
                    url = server.url(name, RUNNER)
                result = _writers(url, writers, args.events, (args.paced_events, args.paced_rate))
                a, p, c = result["audit"], result["peer"], result["paced"]
                print(
                    f"{kind:10} {writers} run(s) | back to back: "
                    f"audit log {a['rate']:5.0f} appends/s, p50 {a['p50']:.2f} "
                    f"p95 {a['p95']:.2f} p99 {a['p99']:.2f} max {a['max']:.1f} ms; bare commit {p['rate']:5.0f}/s, "
                    f"p50 {p['p50']:.2f} p95 {p['p95']:.2f} ms; p95 ratio {a['p95'] / p['p95']:.1f} | "
                    f"paced {args.paced_rate:g}/s per run: p50 {c['p50']:.2f} p95 {c['p95']:.2f} p99 {c['p99']:.2f} "
                    f"max {c['max']:.1f} ms",
                    flush=True,
                )
        for kind in kinds:
            if kind == "sqlite":
                url = f"sqlite:///{tmp}/report.db"
                AuditLog(url).close()
            else:
                name = server.new_database()
                AuditLog(server.url(name, OWNER)).close()
                url = server.url(name, RUNNER)
            times = _report_time(url, args.report_events)
            print(
                f"{kind:10} report of {args.report_events} events: read {times['read']:.2f} s, verify "
                f"{times['verify']:.2f} s, caretaker report (new process) {times['report']:.2f} s",
                flush=True,
            )
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
