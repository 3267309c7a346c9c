"""A ground supervising N habitats over a long, lossy link: its whole cost per habitat and how late events reach it.

For each N: N emulated habitats (tests/support/emulated_habitat.py: real ``caretaker bridge``,
``caretaker link --delay --loss`` and ``caretaker onboard`` processes, the simulated IVA robot at
the recorded robot's pace), a ground database on a temporary PostgreSQL cluster, one ``caretaker
supervise`` of all N bindings (two with ``--kill-at``), a console (``caretaker serve
--via-supervisor``) with its fleet view open in Chromium; then an IVA run handed to each habitat
as the console hands an operator's start (its set-up, then ``console.onboard_launch.hand_onboard``,
here in the bench's own process, a thread each), all at once or, with ``--hand-over S``, one
after another over S seconds, until every run has ended. Reports (bench/fleet_ground.py says how each is read):

- the habitats' CPU (bridge, link, onboard: on the same two cores, what the ground competes with);
- the ground's CPU from the handing to the last run's end and its memory (peak RSS, and PSS:
  shared pages once), per habitat, of the supervisors, the console and PostgreSQL together, and
  which part took what; beside it the CPU the handing took (the handing threads', summed);
- PostgreSQL's transactions (reads too) and rows written (inserted, updated) per second over that span;
- event delay: from each event's time on the habitat (one machine: one clock) to its change notice
  from the ground database (LISTEN, here), and from each instruction's start on the habitat to the
  console's fleet view first showing it as the robot's current one: p50, p95, max (and the
  screen's minus the one-way light time);
- that every ground chain equals its habitat's, hash for hash, no event twice (fails otherwise).

With ``--kill-at N`` it measures N once more with two supervisors and SIGKILLs the one holding
more runs once a command result of one of its runs is stored: the takeover time is from the kill
to the survivor's last ``TAKEN OVER`` line. Each measurement runs in a process of its own (each
habitat holds one of the machine's ROS domains for the life of its process).

    .venv/bin/python bench/fleet.py [--habitats 1 10 25 50] [--delay 1.3] [--loss 1] [--kill-at 25] [--hand-over S]
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "tests")]  # bench.fleet_ground; support, as the tests import it
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")  # as the tests' sessions (conftest.py)

from bench.fleet_ground import (  # noqa: E402
    GroundCost,
    chain_problems,
    database_writes,
    fleet_screen,
    postmaster_pid,
)
from caretaker.command_options import DEFAULT_SYSREP_DIR  # noqa: E402
from console.onboard_launch import SecondOperator, hand_onboard  # noqa: E402
from flight.flight_support import CLEAN_FILTER, PROCEDURE  # noqa: E402
from ground.change_feed import ChangeNotice, open_change_feed  # noqa: E402
from pride.executive import Mode  # noqa: E402
from pride.robot_sides import robot_side_for  # noqa: E402
from pride.run_setup import RunSetup, load_sysreps  # noqa: E402
from records.audit_log import AuditLog  # noqa: E402
from records.onboard_handoffs import OnboardHandoffs  # noqa: E402
from records.releases import ReleaseStore, version_for_run  # noqa: E402
from support.emulated_habitat import EmulatedHabitat, fleet, kill_the_busier, supervise  # noqa: E402
from support.postgres import OWNER, RUNNER, postgres_server  # noqa: E402
from support.processes import ManagedProcess, caretaker  # noqa: E402
from support.web_server import PEOPLE, add_people  # noqa: E402

RUN_TIMEOUT_S = 1800.0
TAKEOVER_TIMEOUT_S = 300.0
_RESULT = "FLEET-RESULT "


class Arrivals:
    """When each event's change notice reached this process ((run, seq) -> time.time()), which
    kinds were stored per run, and which runs' handoffs ended."""

    def __init__(self) -> None:
        self.at: dict[tuple[str, int], float] = {}
        self.kinds: set[tuple[str, str]] = set()
        self.ended: set[str] = set()
        self.changed = threading.Condition()

    def notice(self, change: ChangeNotice) -> None:  # events: "<seq> <kind> <run>"; handoffs: "<state> <run>"
        now = time.time()
        words = change.payload.split()
        with self.changed:
            if change.channel == "events" and len(words) == 3:
                self.at.setdefault((words[2], int(words[0])), now)
                self.kinds.add((words[2], words[1]))
            elif change.channel == "handoffs" and words[:1] == ["ended"]:
                self.ended.add(words[-1])
            self.changed.notify_all()

    def wait_for(self, done: object, what: str, timeout: float = RUN_TIMEOUT_S) -> None:
        with self.changed:
            if not self.changed.wait_for(done, timeout):  # type: ignore[arg-type]
                raise SystemExit(f"not within {timeout:g} s: {what}")


@dataclass
class Measured:
    """One measurement, as the child process hands it to the table."""

    habitats: int
    supervisors: int
    completed: int
    up_s: float
    wall_s: float
    cpu_s: dict[str, float]  # part (supervisors, console, postgres, ground) -> CPU s over the span
    handing_cpu_s: float  # the threads that handed the runs, together
    peak_rss_mb: dict[str, float]
    peak_pss_mb: dict[str, float]
    commits_per_s: float
    rows_per_s: float
    db_delay_ms: tuple[float, float, float]
    unannounced: int  # events stored whose change notice never came
    screen_delay_ms: tuple[float, float, float]
    screen_shown: tuple[int, int]  # instructions shown, started
    chains_equal: int
    takeover_s: float | None


def _spread_ms(values: list[float]) -> tuple[float, float, float]:
    """p50, p95, max in ms."""
    if not values:
        raise SystemExit("no delays measured")
    ordered = sorted(values)
    p95 = ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]
    return 1000 * statistics.median(ordered), 1000 * p95, 1000 * ordered[-1]


def _console(db: str, habitats: list[EmulatedHabitat], folder: Path, env: dict[str, str]) -> tuple[ManagedProcess, str]:
    """``caretaker serve --via-supervisor`` of every habitat's binding (linked into one folder)."""
    bindings = folder / "console-bindings"
    bindings.mkdir()
    for habitat in habitats:
        (bindings / habitat.binding.name).symlink_to(habitat.binding)
    process = caretaker(
        *("serve", "--via-supervisor", "--db", db, "--bindings", str(bindings), "--port", "0"),
        *("--reports", str(folder / "reports")),
        env=env,
        name="serve",
    )
    return process, process.wait_ready(180).split()[-1]


def _hand(habitat: EmulatedHabitat, audit: AuditLog) -> tuple[str, float]:
    """Hand ``habitat`` its IVA run as a console hands an operator's start (the same set-up, then
    console.onboard_launch.hand_onboard), autonomous, its manual instructions marked done and the
    unlock approved by bob; the run's id once the habitat took it, and the CPU this took here."""
    begun = time.thread_time()
    setup = RunSetup.prepare(
        PROCEDURE,
        robot_side_for(habitat.binding),  # the emulated habitat's deployment beside its binding
        load_sysreps([DEFAULT_SYSREP_DIR]),
        version=lambda checked, side: version_for_run(
            ReleaseStore(audit.engine), checked, PROCEDURE.name, side, rehearsal=True
        ),
    )
    run_id = hand_onboard(
        setup,
        habitat.binding,
        audit,
        user="flight",
        mode=Mode.AUTONOMOUS,
        approver=SecondOperator("bob", PEOPLE["bob"][2]),
        rosbridge=None,
        confirm_manual=True,
        values={"clean_filter_id": CLEAN_FILTER},
        ready_within=600,
    )
    return run_id, time.thread_time() - begun


def measure(count: int, delay: float, loss: float, kill: bool, hand_over: float) -> Measured:
    """One fleet of ``count`` habitats, each link ``delay`` s one way losing the share ``loss``, the
    runs handed over ``hand_over`` s (0: at once)."""
    with tempfile.TemporaryDirectory(prefix="caretaker-fleet-") as scratch, postgres_server() as server:
        folder = Path(scratch)
        name = server.new_database()
        db, owner = server.url(name, RUNNER), server.url(name, OWNER)
        add_people(owner)
        env = {**os.environ, "TMPDIR": scratch}
        audit, arrivals = AuditLog(db), Arrivals()
        feed = open_change_feed(audit.engine)
        feed.subscribe(arrivals.notice)
        started, takeover = time.monotonic(), None
        try:
            if not feed.connected.wait(30):
                raise SystemExit("the ground database's change feed did not connect")
            with fleet(folder, env, [delay] * count, loss=loss) as habitats:
                up = time.monotonic() - started
                print(f"{count} habitat(s) up in {up:.0f} s", flush=True)
                console, url = _console(db, habitats, folder, env)
                supervisors = [supervise(db, habitats, env, f"supervise-{n}") for n in range(1, 2 + kill)]
                try:
                    with fleet_screen(url, [h.name for h in habitats]) as screen:
                        cost = GroundCost(
                            {
                                "supervisors": [p.proc.pid for p, _ in supervisors],
                                "console": [console.proc.pid],
                                "postgres": [postmaster_pid(server.data_dir)],
                            },
                            beside={"habitats": [p.proc.pid for h in habitats for p in (h.bridge, h.link, h.onboard)]},
                        )
                        writes0, t0 = database_writes(owner), time.monotonic()
                        cost.start()
                        with concurrent.futures.ThreadPoolExecutor(count, thread_name_prefix="hand") as pool:
                            handed = []
                            for n, habitat in enumerate(habitats):
                                time.sleep(max(0.0, t0 + n * hand_over / count - time.monotonic()))  # the load's pace
                                handed.append(pool.submit(_hand, habitat, audit))
                            run_ids = [future.result()[0] for future in handed]
                            handing = sum(future.result()[1] for future in handed)
                        if kill:
                            killed = kill_the_busier(
                                supervisors,
                                run_ids,
                                OnboardHandoffs(audit.engine),
                                lambda runs: arrivals.wait_for(
                                    lambda: any((r, "command_result") in arrivals.kinds for r in runs),
                                    "a command result of its runs",
                                ),
                                within=TAKEOVER_TIMEOUT_S,
                            )
                            print(
                                f"  killed {killed.victim} holding {len(killed.held[killed.victim])} of "
                                f"{len(run_ids)} runs; {killed.survivor} took them over"
                            )
                            takeover = killed.seconds
                        arrivals.wait_for(lambda: arrivals.ended >= set(run_ids), "every run ended")
                        costs, wall = cost.stop(), time.monotonic() - t0
                        time.sleep(1.5)  # pg_stat_database: backends report their counts within a second
                        writes = [after - before for after, before in zip(database_writes(owner), writes0, strict=True)]
                        runs = {h.name: run_id for h, run_id in zip(habitats, run_ids, strict=True)}
                        screen_delays, missed = screen.delays(audit, runs)
                finally:
                    for process in [*(p for p, _ in supervisors), console]:
                        process.stop()
                problems = chain_problems(audit, runs, habitats)
                handoffs = OnboardHandoffs(audit.engine)
                results = [getattr(handoffs.get(r), "result", None) for r in run_ids]
            stored = [event for run_id in run_ids for event in audit.stored_events(run_id)]
        finally:
            feed.close()
            audit.close()
    # a notice is sent after the commit, best effort (records/audit_log.py _Announcer): one may be missing
    unannounced = [e for e in stored if (e.run_id, e.seq) not in arrivals.at]
    if unannounced:
        print(f"  {len(unannounced)} event(s) stored without a change notice:", flush=True)
        for e in unannounced:
            print(f"    {e.run_id} seq {e.seq} {e.kind} {e.time:%H:%M:%S.%f}Z", flush=True)
    db_delays = [
        arrivals.at[(e.run_id, e.seq)] - e.time.astimezone(UTC).timestamp() for e in stored if e not in unannounced
    ]
    if problems:
        raise SystemExit("chains not equal:\n" + "\n".join(problems))
    for part, c in costs.items():
        memory = f", peak RSS {c.peak_rss_mb:.0f} MB, PSS {c.peak_pss_mb:.0f} MB" if part != "habitats" else ""
        print(f"  {part}: CPU {c.cpu_s:.1f} s{memory}", flush=True)
    return Measured(
        habitats=count,
        supervisors=len(supervisors),
        completed=results.count("completed"),
        up_s=up,
        wall_s=wall,
        cpu_s={part: c.cpu_s for part, c in costs.items()},
        handing_cpu_s=handing,
        peak_rss_mb={part: c.peak_rss_mb for part, c in costs.items()},
        peak_pss_mb={part: c.peak_pss_mb for part, c in costs.items()},
        commits_per_s=writes[0] / wall,
        rows_per_s=writes[1] / wall,
        db_delay_ms=_spread_ms(db_delays),
        unannounced=len(unannounced),
        screen_delay_ms=_spread_ms(screen_delays),
        screen_shown=(len(screen_delays), len(screen_delays) + missed),
        chains_equal=count - len({p.split(":")[0] for p in problems}),
        takeover_s=takeover,
    )


def _row(m: Measured, delay: float) -> str:
    """One row of the table (docs/benchmarks.md, "fleet")."""
    per = m.habitats
    parts = "/".join(f"{m.cpu_s[p] / per:.2f}" for p in ("supervisors", "console", "postgres"))
    db = " / ".join(f"{v:.0f}" for v in m.db_delay_ms) + (f" ({m.unannounced} without notice)" if m.unannounced else "")
    screen = " / ".join(f"{v:.0f}" for v in m.screen_delay_ms)
    beyond = " / ".join(f"{v - 1000 * delay:.0f}" for v in m.screen_delay_ms)
    cores = sum(m.cpu_s[part] for part in ("ground", "habitats")) / m.wall_s
    kill = f"killed 1 of 2, taken over in {m.takeover_s:.1f} s" if m.takeover_s is not None else f"{m.supervisors}"
    return (
        f"| {m.habitats} | {kill} | {m.completed} of {m.habitats} | {m.wall_s:.0f} s "
        f"| {m.cpu_s['ground'] / per:.2f} s ({parts}) + {m.handing_cpu_s / per:.2f} s "
        f"| {m.cpu_s['habitats'] / per:.2f} s | {cores:.2f} "
        f"| {m.peak_rss_mb['ground'] / per:.0f} / {m.peak_pss_mb['ground'] / per:.0f} MB "
        f"| {m.commits_per_s:.0f} / {m.rows_per_s:.0f} | {db} ms "
        f"| {screen} ms ({beyond}; {m.screen_shown[0]} of {m.screen_shown[1]}) "
        f"| {m.chains_equal} of {m.habitats} |"
    )


HEADER = (
    "| habitats | supervisors | runs completed | wall "
    "| ground CPU per habitat (supervisors/console/PostgreSQL) + handing it its run "
    "| habitat CPU per habitat | cores busy (ground + habitats) "
    "| ground peak RSS / PSS per habitat | PostgreSQL transactions / rows written per s "
    "| event delay to ground db p50 / p95 / max "
    "| to the console's screen p50 / p95 / max (beyond the light time; instructions shown) | chains equal |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|"
)


class MeasurementFailed(RuntimeError):
    """A child's measurement ended without a result (what it printed says why)."""


def _measure_apart(count: int, args: argparse.Namespace, kill: bool) -> Measured:
    """:func:`measure` in a child process (its habitats' ROS domains are released when it ends)."""
    command = [sys.executable, __file__, "--one", str(count), "--delay", str(args.delay), "--loss", str(args.loss)]
    command += ["--hand-over", str(args.hand_over)]
    child = subprocess.Popen([*command, *(["--kill"] if kill else [])], stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    result = None
    try:
        for line in child.stdout:
            if line.startswith(_RESULT):
                result = Measured(**json.loads(line.removeprefix(_RESULT)))
            else:
                print(line, end="", flush=True)
    except KeyboardInterrupt:
        child.send_signal(signal.SIGINT)
        raise
    if child.wait() != 0 or result is None:
        raise MeasurementFailed(f"the measurement of {count} habitat(s) failed (exit {child.returncode}): see above")
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument(
        "--habitats", type=int, nargs="+", default=[1, 10, 25, 50], metavar="N", help="fleet sizes, one after another"
    )
    parser.add_argument(
        "--delay", type=float, default=1.3, metavar="S", help="each link's one-way delay (s; Gateway: 1.3)"
    )
    parser.add_argument(
        "--loss", type=float, default=1.0, metavar="PCT", help="each link's segment loss, each way (%%)"
    )
    parser.add_argument(
        "--kill-at", type=int, default=25, metavar="N", help="N habitats, two supervisors, one killed (0: none)"
    )
    parser.add_argument(
        "--hand-over",
        type=float,
        default=0.0,
        metavar="S",
        help="hand the runs one after another over S s (0: at once)",
    )
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # a child's single measurement
    parser.add_argument("--kill", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one is not None:
        print(
            _RESULT + json.dumps(asdict(measure(args.one, args.delay, args.loss / 100, args.kill, args.hand_over))),
            flush=True,
        )
        return
    if min(args.habitats) < 1 or args.kill_at < 0:
        parser.error("--habitats: one habitat or more each; --kill-at: one or more, or 0 for none")
    sizes = [(n, False) for n in args.habitats] + ([(args.kill_at, True)] if args.kill_at else [])
    if not 0 <= args.loss < 100:
        parser.error("--loss: a percentage from 0 to under 100")
    print(
        f"fleet: link {args.delay:g} s one way, {args.loss:g} % loss, runs handed "
        f"{f'over {args.hand_over:g} s' if args.hand_over else 'at once'}; {datetime.now(UTC):%Y-%m-%d %H:%M}Z",
        flush=True,
    )
    rows, failures = [], []
    for count, kill in sizes:  # a size that fails does not keep the others from being measured
        try:
            rows.append(_row(_measure_apart(count, args, kill), args.delay))
            print(rows[-1], flush=True)
        except MeasurementFailed as failure:
            failures.append(str(failure))
    print(HEADER, *rows, sep="\n")
    if failures:
        raise SystemExit("\n".join(failures))


if __name__ == "__main__":
    main()
