"""One ground supervising N habitats: its CPU and memory per habitat, and how late events reach it.

Starts N emulated habitats (tests/support/emulated_habitat.py: real ``caretaker bridge``, ``caretaker
link`` and ``caretaker onboard`` processes, the simulated IVA robot at the recorded robot's pace),
a ground database on a temporary PostgreSQL cluster and one ``caretaker supervise`` of all N
bindings, then hands each habitat an IVA run at once (``caretaker run --onboard --via-supervisor``)
and waits until every run has ended. Reports:

- ``supervisor CPU``: the supervise process's user + system CPU from READY to the last run's end,
  in all and per habitat, and as a share of one core over that time;
- ``RSS``: its resident memory at the end and at its peak (VmHWM): what each habitat adds is the
  difference between runs of different N;
- ``event delay``: for every event of every run, from its time on the habitat (the onboard
  executive's clock; one machine here) to its change notice from the ground database (LISTEN, in
  this process): p50, p95, max.

    .venv/bin/python bench/fleet.py --habitats N [--delay S]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
from datetime import UTC, datetime
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")  # as the tests' sessions (conftest.py)

from ground.change_feed import ChangeNotice, open_change_feed  # noqa: E402
from pride.approvals import APPROVER_PASSWORD_ENV  # noqa: E402
from records.audit_log import AuditLog  # noqa: E402
from support.emulated_habitat import fleet, supervise  # noqa: E402
from support.postgres import OWNER, RUNNER, postgres_server  # noqa: E402
from support.web_server import PEOPLE, add_people  # noqa: E402

RUN_TIMEOUT_S = 900.0
_TICK = os.sysconf("SC_CLK_TCK")


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / _TICK


def _memory_mb(pid: int) -> dict[str, float]:
    """VmRSS and VmHWM of process ``pid`` (MB)."""
    status = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
    return {key: int(status[key].split()[0]) / 1024 for key in ("VmRSS", "VmHWM")}


class Arrivals:
    """When each event's change notice reached this process: (run, seq) -> time.time()."""

    def __init__(self) -> None:
        self.at: dict[tuple[str, int], float] = {}
        self.ended: set[str] = set()
        self.changed = threading.Condition()

    def notice(self, change: ChangeNotice) -> None:  # events: "<seq> <kind> <run>"; handoffs: "<state> <run>"
        now = time.time()
        words = change.payload.split()
        with self.changed:
            if change.channel == "events" and len(words) == 3:
                self.at.setdefault((words[2], int(words[0])), now)
            elif change.channel == "handoffs" and words[:1] == ["ended"]:
                self.ended.add(words[-1])
            self.changed.notify_all()


def _percentile(values: list[float], share: float) -> float:
    return sorted(values)[min(len(values) - 1, round(share * (len(values) - 1)))]


def measure(count: int, delay: float) -> None:
    with tempfile.TemporaryDirectory(prefix="caretaker-fleet-") as scratch, postgres_server() as server:
        folder = Path(scratch)
        name = server.new_database()
        db, owner = server.url(name, RUNNER), server.url(name, OWNER)
        add_people(owner)
        env = {**os.environ, APPROVER_PASSWORD_ENV: PEOPLE["bob"][2], "TMPDIR": scratch}
        audit = AuditLog(db)
        arrivals = Arrivals()
        feed = open_change_feed(audit.engine)
        feed.subscribe(arrivals.notice)
        started = time.monotonic()
        try:
            assert feed.connected.wait(30), "the ground database's change feed did not connect"
            with fleet(folder, env, [delay] * count) as habitats:
                up = time.monotonic() - started
                supervisor, _ = supervise(db, habitats, env, "supervise")
                pid = supervisor.proc.pid
                try:
                    cpu0, t0 = _cpu_s(pid), time.monotonic()
                    runners = [h.hand_run(db, env) for h in habitats]
                    run_ids = [r.wait_for_line(r"^READY run ", 300).split()[-1] for r in runners]
                    with arrivals.changed:
                        if not arrivals.changed.wait_for(lambda: arrivals.ended >= set(run_ids), RUN_TIMEOUT_S):
                            raise SystemExit(f"runs not ended in {RUN_TIMEOUT_S:g} s: {set(run_ids) - arrivals.ended}")
                    cpu, wall, memory = _cpu_s(pid) - cpu0, time.monotonic() - t0, _memory_mb(pid)
                    results = [r.wait_for_line(r"^RESULT ", 60).split()[1] for r in runners]
                    for runner in runners:
                        runner.stop()
                finally:
                    supervisor.stop()
            delays = []
            for run_id in run_ids:
                for event in audit.events(run_id):
                    habitat_time = event.time.astimezone(UTC).timestamp()
                    delays.append(arrivals.at[(run_id, event.seq)] - habitat_time)
        finally:
            feed.close()
            audit.close()
    print(f"fleet: {count} habitat(s), link {delay:g} s one way, {datetime.now(UTC):%Y-%m-%d %H:%M}Z")
    print(f"  habitats up in {up:.1f} s; runs: {', '.join(sorted(set(results)))} ({len(results)}); {wall:.1f} s")
    print(f"  supervisor CPU: {cpu:.2f} s ({cpu / count:.2f} s per habitat, {100 * cpu / wall:.1f} % of a core)")
    print(f"  supervisor RSS: {memory['VmRSS']:.0f} MB at the end, peak {memory['VmHWM']:.0f} MB")
    print(
        f"  event delay habitat -> ground db ({len(delays)} events): p50 {1000 * statistics.median(delays):.0f} ms, "
        f"p95 {1000 * _percentile(delays, 0.95):.0f} ms, max {1000 * max(delays):.0f} ms"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--habitats", type=int, required=True, metavar="N", help="emulated habitats (one run each)")
    parser.add_argument("--delay", type=float, default=0.1, metavar="S", help="each link's one-way delay (s)")
    args = parser.parse_args()
    if args.habitats < 1:
        parser.error("--habitats: at least 1")
    measure(args.habitats, args.delay)


if __name__ == "__main__":
    main()
