"""What bench/fleet.py measures of the ground: its processes' cost, PostgreSQL's writes, a console's screen, the chains.

- :class:`GroundCost`: CPU and memory of the ground's process trees (the supervisors, a console,
  the PostgreSQL cluster: the postmaster and every backend it forked), from /proc. CPU counts the
  children that ended too (their time is in the parent's ``cutime``/``cstime`` once reaped), so a
  backend that lived a second still counts. Memory is sampled every second for its peak: RSS
  summed over the processes, and PSS, where pages shared by several (PostgreSQL's shared buffers,
  the forked backends' libraries) count once in all.
- :func:`database_writes`: the database's commits and rows written so far (pg_stat_database).
- :class:`FleetScreen`: a console's fleet view in Chromium, and when it first showed each robot's
  new current instruction.
- :func:`chain_problems`: every ground chain against its habitat's, hash for hash.
"""

from __future__ import annotations

import os
import re
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from playwright.sync_api import sync_playwright
from sqlalchemy import create_engine, text

from records.audit_chain import verify_chain
from records.audit_log import AuditLog
from support.browser import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS
from support.emulated_habitat import EmulatedHabitat
from support.operator_page import sign_in_on

__all__ = [
    "FleetScreen",
    "GroundCost",
    "chain_problems",
    "database_writes",
    "fleet_screen",
    "postmaster_pid",
]

_TICK = os.sysconf("SC_CLK_TCK")
SAMPLE_S = 1.0


def _descendants(pid: int) -> list[int]:
    """``pid`` and every live process below it."""
    found, queue = [], [pid]
    while queue:
        current = queue.pop()
        found.append(current)
        try:
            tasks = list(Path(f"/proc/{current}/task").glob("*/children"))
        except FileNotFoundError:  # the process ended while we looked
            continue
        for task in tasks:
            try:
                queue += [int(child) for child in task.read_text().split()]
            except FileNotFoundError:  # the thread ended while we looked
                continue
    return found


def _process_cpu_s(pid: int) -> float:
    """User + system CPU seconds of ``pid`` and of its children it reaped (0 if it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (FileNotFoundError, ProcessLookupError):
        return 0.0
    return sum(int(value) for value in fields[11:15]) / _TICK


def _memory_kb(pid: int) -> tuple[int, int]:
    """(Rss, Pss) of ``pid`` in kB, (0, 0) if it is gone."""
    try:
        rollup = Path(f"/proc/{pid}/smaps_rollup").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return 0, 0
    values = dict(re.findall(r"^(Rss|Pss):\s+(\d+) kB", rollup, re.MULTILINE))
    return int(values.get("Rss", 0)), int(values.get("Pss", 0))


def postmaster_pid(data_dir: Path) -> int:
    """The cluster's postmaster, from the first line of its postmaster.pid."""
    return int((data_dir / "postmaster.pid").read_text().split()[0])


@dataclass
class PartCost:
    """One ground part's process trees: CPU over the measured span, memory at its end and peak (MB)."""

    cpu_s: float = 0.0
    rss_mb: float = 0.0
    pss_mb: float = 0.0
    peak_rss_mb: float = 0.0
    peak_pss_mb: float = 0.0


@dataclass
class GroundCost:
    """The ground's parts (name -> root pids), sampled from :meth:`start` until :meth:`stop`;
    ``beside``: parts on the same machine that are not the ground's (the habitats), CPU only.

    A part whose process is killed keeps the CPU it had used when last sampled."""

    parts: dict[str, list[int]]
    beside: dict[str, list[int]] = field(default_factory=dict)
    costs: dict[str, PartCost] = field(default_factory=dict)
    _cpu0: dict[str, float] = field(default_factory=dict)
    _last_cpu: dict[str, float] = field(default_factory=dict)
    _stopped: threading.Event = field(default_factory=threading.Event)
    _sampler: threading.Thread | None = None

    def _cpu(self, part: str) -> float:
        roots = self.parts.get(part) or self.beside[part]
        return sum(_process_cpu_s(pid) for root in roots for pid in _descendants(root))

    def _sample(self) -> None:
        total_rss = total_pss = 0.0
        for part, roots in self.parts.items():
            memory = [_memory_kb(pid) for root in roots for pid in _descendants(root)]
            cost = self.costs[part]
            cost.rss_mb, cost.pss_mb = (sum(m[i] for m in memory) / 1024 for i in (0, 1))
            cost.peak_rss_mb, cost.peak_pss_mb = max(cost.peak_rss_mb, cost.rss_mb), max(cost.peak_pss_mb, cost.pss_mb)
            self._last_cpu[part] = max(self._last_cpu.get(part, 0.0), self._cpu(part))
            total_rss, total_pss = total_rss + cost.rss_mb, total_pss + cost.pss_mb
        for part in self.beside:
            self._last_cpu[part] = max(self._last_cpu.get(part, 0.0), self._cpu(part))
        whole = self.costs.setdefault("ground", PartCost())
        whole.rss_mb, whole.pss_mb = total_rss, total_pss
        whole.peak_rss_mb, whole.peak_pss_mb = max(whole.peak_rss_mb, total_rss), max(whole.peak_pss_mb, total_pss)

    def _run(self) -> None:
        while not self._stopped.wait(SAMPLE_S):
            self._sample()

    def start(self) -> None:
        for part in [*self.parts, *self.beside]:
            self.costs[part] = PartCost()
            self._cpu0[part] = self._last_cpu[part] = self._cpu(part)
        self._sample()
        self._sampler = threading.Thread(target=self._run, name="ground-cost", daemon=True)
        self._sampler.start()

    def stop(self) -> dict[str, PartCost]:
        """The parts' costs, the beside parts' (CPU only) and the ground's (``"ground"``: the
        parts' sums) over the span."""
        self._stopped.set()
        if self._sampler is not None:
            self._sampler.join()
        self._sample()
        for part in [*self.parts, *self.beside]:
            self.costs[part].cpu_s = self._last_cpu[part] - self._cpu0[part]
        self.costs["ground"].cpu_s = sum(self.costs[part].cpu_s for part in self.parts)
        return self.costs


def database_writes(owner_url: str) -> tuple[int, int]:
    """(transactions committed, rows inserted + updated) in the database so far, as its owner reads
    pg_stat_database (a backend reports its counts within about a second)."""
    engine = create_engine(owner_url)
    try:
        with engine.connect() as connection:
            connection.execute(text("SELECT pg_stat_clear_snapshot()"))
            commits, rows = connection.execute(
                text(
                    "SELECT xact_commit, tup_inserted + tup_updated FROM pg_stat_database "
                    "WHERE datname = current_database()"
                )
            ).one()
    finally:
        engine.dispose()
    return int(commits), int(rows)


#: Records, for each robot of the fleet view, every instruction its row newly shows as current and
#: when (Date.now()): the rows are replaced on every push or read, so the whole list is looked at.
_OBSERVE = """() => {
    window.fleetSeen = [];
    const shown = {};
    const look = () => {
        const now = Date.now();
        for (const row of document.querySelectorAll('#fleet-list > li[data-robot]')) {
            const meta = [...row.querySelectorAll('.meta')].map(m => m.textContent).join(' ');
            const at = / · at (\\S+) · /.exec(meta);
            const instruction = at ? at[1] : '';
            if (shown[row.dataset.robot] !== instruction) {
                shown[row.dataset.robot] = instruction;
                if (instruction) window.fleetSeen.push([row.dataset.robot, instruction, now]);
            }
        }
    };
    new MutationObserver(look).observe(document.querySelector('#fleet-list'),
                                       {childList: true, subtree: true, characterData: true});
    look();
}"""


@dataclass
class FleetScreen:
    """What a console's fleet view showed: (robot, instruction, seconds since the epoch) in order."""

    read: Callable[[], list[tuple[str, str, float]]]

    def delays(self, audit: AuditLog, runs: dict[str, str]) -> tuple[list[float], int]:
        """For each instruction started in ``runs`` (robot -> run id), from its time on the habitat
        to when the screen first showed it for that robot after that time; (the delays, how many
        started instructions the screen never showed: passed while no push or read came)."""
        seen = self.read()
        delays, missed = [], 0
        for robot, run_id in runs.items():
            for event in audit.stored_events(run_id):
                if event.kind != "instruction_started":
                    continue
                started = event.time.timestamp()
                shown = [t for r, i, t in seen if r == robot and i == event.instruction and t >= started]
                if shown:
                    delays.append(shown[0] - started)
                else:
                    missed += 1
        return delays, missed


@contextmanager
def fleet_screen(console_url: str, robots: Sequence[str]) -> Iterator[FleetScreen]:
    """Chromium (as tests/support/browser.py starts it) on the console's page, alice signed in,
    watching the fleet view once it lists every robot of ``robots``."""
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_context(viewport={"width": 1500, "height": 1000}).new_page()
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.set_default_timeout(TIMEOUT_MS)
            page.goto(console_url)
            sign_in_on(page, "alice")
            page.evaluate(_OBSERVE)

            def read() -> list[tuple[str, str, float]]:
                if errors:
                    raise RuntimeError("the console's page raised script errors:\n" + "\n".join(errors))
                return [(robot, instruction, ms / 1000) for robot, instruction, ms in page.evaluate("fleetSeen")]

            yield FleetScreen(read)
        finally:
            browser.close()


def chain_problems(audit: AuditLog, runs: dict[str, str], habitats: Sequence[EmulatedHabitat]) -> list[str]:
    """What differs between each run's ground chain and its habitat's ((seq, kind, hash), a seq
    stored twice, a broken chain); empty when every chain is equal. ``runs``: robot -> run id."""
    problems = []
    for habitat in habitats:
        run_id = runs[habitat.name]
        ground, onboard = audit.stored_events(run_id), habitat.onboard_chain(run_id)
        check = verify_chain(run_id, ground)
        if not check.ok:
            problems.append(f"{run_id}: ground chain broken: {check.describe()}")
        if len({e.seq for e in ground}) != len(ground):
            problems.append(f"{run_id}: a seq stored twice on the ground")
        if [(e.seq, e.kind, e.hash) for e in ground] != [(e.seq, e.kind, e.hash) for e in onboard]:
            problems.append(f"{run_id}: ground {len(ground)} events, habitat {len(onboard)}, not equal")
        if not onboard or onboard[-1].kind != "run_completed":
            problems.append(f"{run_id}: the habitat's run did not complete")
    return problems
