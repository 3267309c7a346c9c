"""The habitat's onboard runs: take a unit from the ground, run it with PAX here, hand its events down.

One :class:`HabitatRuns` per habitat (``caretaker onboard`` holds it). It keeps, under its state
folder:

- ``onboard.sqlite``: every onboard run's events in the audit log's own append-only, hash-chained
  table (:class:`records.audit_log.AuditLog` on SQLite), and robot control as on the ground: the
  record that survives a restart, and the one the ground's copy must equal hash for hash;
- ``units/<hash>/``: each accepted unit as it arrived (``unit.json``) and its procedure files;
- ``actions.jsonl``: every operator action by key (when it arrived and was answered, on the
  habitat's clock, and its outcome), so a resend is never acted on twice.

A run answers by itself only what the unit answered at uplink (record values, manual
instructions, hazardous commands); any other hold waits for an operator's action from the ground,
while everything automatable runs on without waiting for the link.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from pride.approvals import ApprovalPolicy, CarriedApproval, command_name
from pride.events import EventKind
from pride.executive import Executive, Hold, Mode, OperatorActionError, RobotControlled, RunStatus, Snapshot
from pride.gateways import open_gateway
from pride.robot_sides import RobotSide, robot_side_for
from pride.run_section import RunSection, SectionError
from pride.run_setup import RunSetup
from pride.states import CarriedApprovalSpent
from pride.systems import SystemGateway
from procedure_language.diagnostics import ProcedureError
from procedure_language.model import CommandInstruction, RecordInstruction
from procedure_language.sysrep import SysRep
from records.audit_chain import StoredEvent, utc
from records.audit_log import AuditLog
from records.robot_control import RobotControl

from .followers import Followers, Following
from .unit import OperatorAction, Unit, UnitError, digest, signed_by
from .unit_answers import UnitAnswers, UplinkAnswer

__all__ = [
    "SECURITY_LOG",
    "ActionAnswer",
    "EventsAnswer",
    "HabitatRuns",
    "HabitatStatus",
    "RunUnitAnswer",
    "UplinkAnswer",
]

log = logging.getLogger(__name__)
#: The logger of security events (refused units and actions): ``caretaker onboard`` prints its records
#: as ``SECURITY ...`` lines, which ``caretaker up`` shows whether or not it echoes its parts.
SECURITY_LOG = "caretaker.security"
security = logging.getLogger(SECURITY_LOG)

#: The most events one answer carries (a long run is caught up in several).
MAX_EVENTS = 200
#: The longest a request for events waits for the next one.
MAX_WAIT_S = 30.0


@dataclass(frozen=True)
class EventsAnswer:
    events: list[dict[str, Any]]
    head_seq: int
    status: str  # active | completed | stopped | interrupted | unknown
    habitat_time: str
    waiting: str = ""  # "N: why" while the run holds for an operator the unit did not answer
    message: str = ""
    snapshot: dict[str, Any] | None = None  # the executive's state (Snapshot.to_json) as of an event sent


@dataclass(frozen=True)
class ActionAnswer:
    state: str  # DONE | REFUSED | EXPIRED
    message: str


@dataclass(frozen=True)
class RunUnitAnswer:
    """The unit an onboard run started from (``RunUnit.srv``'s response)."""

    unit_json: str  # "" when no unit started the run here
    unit_hash: str
    message: str


@dataclass(frozen=True)
class HabitatStatus:
    """What the onboard executive says of itself (``/caretaker_onboard/status``): its active run,
    how many units it has answered in all, and the refusals since it started (security events)."""

    active_run: str  # "" when none
    units_answered: int
    units_refused: int
    actions_refused: int
    since: str  # when this executive started (ISO 8601, UTC): the refusals are counted from then


@dataclass
class _Run:
    unit: Unit
    unit_hash: str
    executive: Executive
    gateway: SystemGateway
    answerer: threading.Thread | None = None
    looked_at: int = -1  # the last event after which the answerer looked at a hold (and left it for the ground)


def stored_event_json(event: StoredEvent) -> dict[str, Any]:
    """A stored event as it goes down: every field the chain covers, and its hash."""
    return {
        "run_id": event.run_id,
        "seq": event.seq,
        "time": utc(event.time).isoformat(timespec="microseconds"),
        "actor": event.actor,
        "kind": event.kind,
        "instruction": event.instruction,
        "data": event.data,
        "prev_hash": event.prev_hash,
        "hash": event.hash,
    }


class HabitatRuns:
    """Units taken, onboard runs, their events and operators' actions on them. Thread-safe."""

    def __init__(
        self,
        state_dir: Path,
        *,
        secret: str,
        bindings: Mapping[str, Path],
        sysreps: Mapping[str, SysRep],
        rosbridge_url: str | None = None,
        gateway_factory: Callable[[str, str | None], SystemGateway] | None = None,
        clock: Callable[[], float] = time.time,
        policy_for: Callable[[Path], ApprovalPolicy] = lambda binding: robot_side_for(binding).approvals,
    ) -> None:
        """``bindings``: the habitat's binding files by file name (a unit names one);
        ``rosbridge_url``: the habitat's bridge as this host reaches it (replaces the bindings'
        address, which is the ground's way in); ``policy_for``: which commands need a second
        operator's approval on the robot side a binding reaches (its deployment's, as on the ground)."""
        self.state_dir = state_dir
        self.units_dir = state_dir / "units"
        self.units_dir.mkdir(parents=True, exist_ok=True)
        self._secret = secret
        self._bindings = dict(bindings)
        self._sysreps = sysreps
        self._rosbridge_url = rosbridge_url
        self._open_gateway = gateway_factory or (lambda path, url: open_gateway(path, rosbridge_url=url))
        self._clock = clock
        self._policy_for = policy_for
        url = f"sqlite:///{state_dir / 'onboard.sqlite'}"
        self.audit = AuditLog(url)
        self.control = RobotControl(url)
        self._lock = threading.Lock()  # units, runs and actions
        self._news = threading.Condition()  # a run's new event: a run emits while _lock may be held
        self._wakes = 0  # how often _news was notified
        self._followers = Followers(self._wake)
        self._runs: dict[str, _Run] = {}
        self._starting: set[str] = set()  # the run of a unit being started (under _lock, read without it)
        self._accepted = {
            path.parent.name: Unit.from_json(path.read_text()) for path in self.units_dir.glob("*/unit.json")
        }
        self._answers = UnitAnswers(
            state_dir / "answers.jsonl",
            (UplinkAnswer("ACCEPTED", h, u.run_id, f"started {u.procedure}") for h, u in self._accepted.items()),
        )
        self._refusals: Counter[str] = Counter()  # refused units and actions since this executive started
        self._started_at = datetime.now(UTC)
        self._actions_file = state_dir / "actions.jsonl"
        self._actions: dict[str, ActionAnswer] = {}
        if self._actions_file.exists():
            for line in self._actions_file.read_text().splitlines():
                record = json.loads(line)
                self._actions[record["key"]] = ActionAnswer(record["state"], record["message"])

    # ---- uplink -----------------------------------------------------------------------------
    def uplink(self, unit_json: str, signature: str) -> UplinkAnswer:
        """Take a unit: check its signature, that it was never answered, its lifetime, binding and
        lint, then start its run.

        Every signed unit is answered once for good (:mod:`onboard.unit_answers`): the same unit again
        gets the first answer (it may have been lost on the link) and starts nothing, and a run id
        that was answered before never starts a run. Refusals are security events: logged always
        (:data:`SECURITY_LOG`) and counted in :meth:`status`.
        """
        unit_hash = digest(unit_json)
        if not signed_by(unit_json, signature, self._secret):
            return self._refused(
                UplinkAnswer(
                    "REFUSED",
                    unit_hash,
                    "",
                    "the unit's signature does not match its contents: changed on the way, or signed with "
                    "another key; not started",
                )
            )
        with self._lock:
            known = self._answers.of_unit(unit_hash)
            if known is None:
                answer = self._answer_unit(unit_json, unit_hash)
                self._answers.keep(answer)
        if known is not None:
            return known if known.state == "ACCEPTED" else self._refused(known, again=True)
        if answer.state == "ACCEPTED":
            log.info("unit %s accepted: onboard run %s (%s)", unit_hash[:12], answer.run_id, answer.message)
            return answer
        return self._refused(answer)

    def _answer_unit(self, unit_json: str, unit_hash: str) -> UplinkAnswer:
        """The one answer to a signed unit never answered before (under ``_lock``)."""
        try:
            unit = Unit.from_json(unit_json)
        except UnitError as exc:
            return UplinkAnswer("REFUSED", unit_hash, "", f"the unit cannot be read: {exc}")

        def refused(message: str, state: str = "REFUSED") -> UplinkAnswer:
            return UplinkAnswer(state, unit_hash, unit.run_id, message)

        earlier = self._answers.of_run(unit.run_id)
        if earlier is not None:
            return refused(
                f"run {unit.run_id} was answered before ({earlier.state} for unit {earlier.unit_hash[:12]}): "
                "a run id starts at most one run; not started"
            )
        now = self._clock()
        if now > unit.expires_at:
            return refused(f"the unit ran out {now - unit.expires_at:.1f} s before it arrived; not started", "EXPIRED")
        busy = [r for r in self._runs.values() if r.executive.snapshot().status is RunStatus.ACTIVE]
        if busy:
            return refused(f"onboard run {busy[0].executive.run_id} is active on this habitat; one unit runs at a time")
        if self.audit.events(unit.run_id):
            return refused(f"run {unit.run_id} already has events here; a unit starts a new run")
        binding = self._bindings.get(unit.binding)
        if binding is None:
            known = ", ".join(sorted(self._bindings)) or "none"
            return refused(f"no binding {unit.binding!r} on this habitat (it has: {known})")
        folder = self.units_dir / unit_hash
        self._starting.add(unit.run_id)  # requests for its events wait for it meanwhile (_status)
        try:
            run = self._start(unit, unit_hash, folder, binding)
        except ProcedureError as exc:
            # as the ground knows the files: by their path in the unit
            problems = "\n".join(str(p).replace(f"{folder}/", "") for p in exc.problems)
            return refused(f"the unit does not lint against this habitat's SysReps:\n{problems}")
        except RobotControlled as exc:
            return refused(str(exc))
        except SectionError as exc:
            return refused(f"the unit's section cannot start: {exc}")
        else:
            (folder / "unit.json").write_text(unit_json)
            self._accepted[unit_hash] = unit
            self._runs[unit.run_id] = run
            return UplinkAnswer("ACCEPTED", unit_hash, unit.run_id, f"started {unit.procedure}")
        finally:  # after the run is in _runs: never a moment where a request finds neither
            self._starting.discard(unit.run_id)

    def _refused(self, answer: UplinkAnswer, *, again: bool = False) -> UplinkAnswer:
        """Log and count a refused unit (a security event: a stale, forged or replayed order)."""
        with self._lock:
            self._refusals["unit"] += 1
        repeat = "sent again, refused as before" if again else answer.state.lower()
        run = f" (run {answer.run_id})" if answer.run_id else ""
        security.warning("unit %s%s %s: %s", answer.unit_hash[:12], run, repeat, answer.message.splitlines()[0])
        return answer

    def _start(self, unit: Unit, unit_hash: str, folder: Path, binding: Path) -> _Run:
        for name, text in unit.files.items():
            path = folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
        try:
            setup = RunSetup.prepare(
                folder / unit.procedure,
                self._side(binding),
                self._sysreps,
                version=lambda *_: unit.version,
                run_id=unit.run_id,
            )
        except ProcedureError:
            _remove(folder)
            raise
        gateway = self._open_gateway(str(binding), self._rosbridge_url)
        executive = setup.executive(gateway, self.audit, mode=Mode(unit.mode), control=self.control)
        executive.add_listener(lambda event: self._wake())
        try:
            for number in unit.breakpoints:
                executive.set_breakpoint(unit.user, number)
            section = unit.section
            executive.start(
                unit.user,
                section=RunSection(str(section["from"]), section["to"], unit.values) if section else None,
                proposal=unit.proposal,
            )
        except (RobotControlled, OperatorActionError, SectionError):
            gateway.close()
            _remove(folder)
            raise
        return self._answering(_Run(unit, unit_hash, executive, gateway))

    def _side(self, binding: Path) -> RobotSide:
        """The robot side a habitat binding reaches: the habitat's robot, with its deployment's approvals."""
        return RobotSide(binding, None, simulator=False, approvals=self._policy_for(binding))

    def _answering(self, run: _Run) -> _Run:
        run.answerer = threading.Thread(
            target=self._answer, args=(run,), name=f"onboard-{run.unit.run_id}", daemon=True
        )
        run.answerer.start()
        return run

    def resume_interrupted(self) -> list[str]:
        """Resume the runs this executive was running when it stopped or crashed (a restart by
        ``caretaker up``): each goes on from its chain, and a command in flight then is sent again
        with its key, so the ledger answers what became of it instead of running it twice. A run
        that cannot be resumed is logged with the reason and stays ``interrupted``. Returns the
        run ids resumed."""
        resumed = []
        for unit_hash, unit in sorted(self._accepted.items(), key=lambda item: item[1].issued_at):
            events = self.audit.events(unit.run_id)
            if not events or events[-1].kind in (EventKind.RUN_COMPLETED, EventKind.RUN_STOPPED):
                continue
            binding = self._bindings.get(unit.binding)
            try:
                if binding is None:
                    raise OperatorActionError(f"its binding {unit.binding} is no longer one of this habitat's")
                setup = RunSetup.resuming(
                    self.units_dir / unit_hash / unit.procedure, self._side(binding), self._sysreps, events
                )
                gateway = self._open_gateway(str(binding), self._rosbridge_url)
                executive = setup.resumed(gateway, self.audit, events, "onboard", control=self.control)
            except (OperatorActionError, ProcedureError, RobotControlled) as exc:
                log.error("onboard run %s cannot be resumed: %s", unit.run_id, exc)
                continue
            executive.add_listener(lambda event: self._wake())
            with self._lock:
                self._runs[unit.run_id] = self._answering(_Run(unit, unit_hash, executive, gateway))
            log.info("onboard run %s resumed from event %d", unit.run_id, events[-1].seq)
            resumed.append(unit.run_id)
        self._wake()
        return resumed

    # ---- answering what the unit answered ----------------------------------------------------
    def _answer(self, run: _Run) -> None:
        """Answer the run's holds that the unit answered at uplink, until it ends; others wait."""
        executive, unit = run.executive, run.unit
        folder = (self.units_dir / run.unit_hash).resolve()
        stale: set[CarriedApproval] = set()  # spent: the ground approves instead
        answered = -1

        def news(s: Snapshot) -> bool:  # ended, or a hold not looked at yet
            return s.status is not RunStatus.ACTIVE or (s.hold is not None and s.last_seq != answered)

        while True:
            snap = executive.wait_for(news)
            assert snap is not None
            if snap.status is not RunStatus.ACTIVE:
                break
            answered = snap.last_seq
            try:
                self._answer_hold(executive, unit, snap, folder, stale)
            except OperatorActionError as exc:  # the hold stays for an operator on the ground
                log.warning("onboard run %s at %s: %s", snap.run_id, snap.current, exc)
            run.looked_at = answered
            self._wake()
        executive.join(30)
        run.gateway.close()
        self._wake()

    @staticmethod
    def _answer_hold(
        executive: Executive, unit: Unit, snap: Snapshot, folder: Path, stale: set[CarriedApproval]
    ) -> None:
        place = executive.current_place()
        if place is None:
            return
        path, instruction = place
        if snap.hold is Hold.OPERATOR_INPUT and isinstance(instruction, RecordInstruction):
            if instruction.name in unit.values:
                executive.enter(unit.user, unit.values[instruction.name])
        elif snap.hold is Hold.OPERATOR_ACTION and unit.confirm_manual:
            executive.mark_done(unit.user)
        elif snap.hold in (Hold.CONFIRMATION, Hold.APPROVAL) and isinstance(instruction, CommandInstruction):
            carried = unit.approval_of(_within(path, folder), instruction.number, command_name(instruction))
            if snap.hold is Hold.CONFIRMATION and (carried is not None or unit.confirm_hazardous):
                executive.confirm(unit.user)  # the sender's ask: approved next (carried), or by the ground
            elif snap.hold is Hold.APPROVAL and carried is not None and carried not in stale:
                try:
                    executive.approve(carried.approver, carried=carried)
                except OperatorActionError as exc:
                    # Spent for good (ran out, another's, or refused on the record): the ground
                    # approves instead. A refusal of the moment (the run changed since ``snap``) is
                    # tried again at the run's next event.
                    if isinstance(exc, CarriedApprovalSpent) or exc.recorded:
                        stale.add(carried)
                    raise

    def _wake(self) -> None:
        with self._news:
            self._wakes += 1
            self._news.notify_all()

    # ---- downlink ---------------------------------------------------------------------------
    def events(self, run_id: str, after_seq: int, wait_s: float = 0.0, max_events: int = 0) -> EventsAnswer:
        """The run's stored events numbered above ``after_seq``; with none, wait up to ``wait_s`` for one."""
        return self._events(run_id, after_seq, wait_s, max_events, None)

    def follow(self, run_id: str, after_seq: int, wait_s: float = 0.0, max_events: int = 0) -> EventsAnswer:
        """As :meth:`events`, for a ground that keeps several requests waiting: each event goes down
        once, the newest request waits for the run's end (:mod:`onboard.followers`), and an answer
        without events carries no snapshot (the ground has the one before)."""
        with self._followers.waiting(run_id, after_seq) as following:
            return self._events(run_id, after_seq, wait_s, max_events, following)

    def _events(
        self, run_id: str, after_seq: int, wait_s: float, max_events: int, following: Following | None
    ) -> EventsAnswer:
        limit = max_events if 0 < max_events <= MAX_EVENTS else MAX_EVENTS
        deadline = time.monotonic() + min(max(wait_s, 0.0), MAX_WAIT_S)

        def read(after: int) -> list[StoredEvent]:
            return self.audit.stored_events(run_id, after=after)

        while True:
            # read outside the lock: a run's every event wakes waiters (_wake), and its PAX thread
            # must not wait for a database read; the count tells a wake-up that came meanwhile
            with self._news:
                seen = self._wakes
            status = self._status(run_id)  # first: the events read next include its last one
            snapshot = self._snapshot(run_id)  # so too: its last_seq is at most the head sent
            due = time.monotonic() >= deadline
            if following is None:
                stored = read(max(after_seq, 0))
                sent, head = stored[:limit], stored[-1].seq if stored else max(after_seq, 0)
                if stored or status != "active" or due:
                    break
            else:
                taken = self._followers.take(following, read, ended=status != "active", due=due, limit=limit)
                if taken is not None:
                    sent, head = taken
                    snapshot = snapshot if sent else None  # the ground has it from the answer before
                    break
            with self._news:
                if self._wakes == seen:
                    self._news.wait(deadline - time.monotonic())
        return EventsAnswer(
            [stored_event_json(e) for e in sent],
            head,
            status,
            datetime.now(UTC).isoformat(timespec="microseconds"),
            self._waiting(run_id),
            "" if status != "unknown" else f"no onboard run {run_id} on this habitat",
            snapshot,
        )

    def _run_of(self, run_id: str) -> _Run | None:
        """The run ``run_id`` if it runs here, read without ``_lock``: an uplink holds that while it
        starts its run (a JVM: seconds, minutes on a loaded habitat), and a request for events must
        neither wait for it nor keep a request thread from a Halt meanwhile (one dict read is atomic)."""
        return self._runs.get(run_id)

    def _snapshot(self, run_id: str) -> dict[str, Any] | None:
        run = self._run_of(run_id)
        return run.executive.snapshot().to_json() if run is not None else None

    def _waiting(self, run_id: str) -> str:
        """ "N: why" when the run holds and its answerer left the hold for an operator, else ""."""
        run = self._run_of(run_id)
        if run is None:
            return ""
        snap = run.executive.snapshot()
        if snap.status is not RunStatus.ACTIVE or snap.hold is None or run.looked_at != snap.last_seq:
            return ""
        number = str(snap.current)
        return snap.reason if snap.reason.startswith(f"{number}:") else f"{number}: {snap.reason or snap.hold.value}"

    def _status(self, run_id: str) -> str:
        """The run's status as its stored events show it: ended only once its last event is stored
        (a unit being started: active, its events to come)."""
        run = self._run_of(run_id)
        # a running run's newest events only (asked on every request for events); another's all
        after = max(run.executive.snapshot().last_seq - 1, 0) if run is not None else 0
        live = run is not None or run_id in self._starting
        events = self.audit.stored_events(run_id, after=after)
        if not events:
            return "active" if live else "unknown"
        ended = {EventKind.RUN_COMPLETED.value: "completed", EventKind.RUN_STOPPED.value: "stopped"}.get(
            events[-1].kind
        )
        return ended or ("active" if live else "interrupted")

    # ---- operators' actions -----------------------------------------------------------------
    def act(self, action_json: str, signature: str) -> ActionAnswer:
        """Take an operator's action on an onboard run (a key already taken is answered as then)."""
        received = self._clock()
        if not signed_by(action_json, signature, self._secret):
            return self._action_refused(
                "?",
                ActionAnswer(
                    "REFUSED",
                    "the action's signature does not match its contents: changed on the way, or signed with "
                    "another key; not acted on",
                ),
            )
        try:
            action = OperatorAction.from_json(action_json)
        except UnitError as exc:
            return self._action_refused("?", ActionAnswer("REFUSED", f"the action cannot be read: {exc}"))
        with self._lock:
            known = self._actions.get(action.key)
        if known is not None:
            return known
        if received > action.expires_at:
            answer = ActionAnswer("EXPIRED", f"{action.action} ran out before it arrived; not acted on")
        else:
            answer = self._perform(action)
        with self._lock:
            self._actions[action.key] = answer
            record = {
                "key": action.key,
                "run_id": action.run_id,
                "action": action.action,
                "user": action.user,
                "received": received,  # the habitat's clock when it arrived
                "answered": self._clock(),
                "state": answer.state,
                "message": answer.message,
            }
            with self._actions_file.open("a") as file:
                file.write(json.dumps(record) + "\n")
        return answer if answer.state == "DONE" else self._action_refused(f"{action.action} {action.key}", answer)

    def _action_refused(self, what: str, answer: ActionAnswer) -> ActionAnswer:
        """Log and count a refused action (a security event, as a refused unit is)."""
        with self._lock:
            self._refusals["action"] += 1
        security.warning("action %s %s: %s", what, answer.state.lower(), answer.message)
        return answer

    def unit_of(self, run_id: str) -> RunUnitAnswer:
        """The unit that started ``run_id`` here, as it arrived (for a ground that attaches to it)."""
        with self._lock:
            found = next(((h, u) for h, u in self._accepted.items() if u.run_id == run_id), None)
        if found is None:
            return RunUnitAnswer("", "", f"no onboard run {run_id} was started on this habitat")
        unit_hash, _ = found
        return RunUnitAnswer((self.units_dir / unit_hash / "unit.json").read_text(), unit_hash, "")

    def status(self) -> HabitatStatus:
        """The active run, the units answered in all, and the refusals since this executive started."""
        with self._lock:
            active = [r.unit.run_id for r in self._runs.values() if r.executive.snapshot().status is RunStatus.ACTIVE]
            refusals = dict(self._refusals)
        return HabitatStatus(
            active[0] if active else "",
            len(self._answers),
            refusals.get("unit", 0),
            refusals.get("action", 0),
            self._started_at.isoformat(timespec="seconds"),
        )

    def _perform(self, action: OperatorAction) -> ActionAnswer:
        with self._lock:
            run = self._runs.get(action.run_id)
        if run is None:
            return ActionAnswer("REFUSED", f"no onboard run {action.run_id} is running on this habitat")
        ex, user, args = run.executive, action.user, action.args
        snap = ex.snapshot()
        if snap.status is not RunStatus.ACTIVE:
            return ActionAnswer("REFUSED", f"onboard run {action.run_id} has ended ({snap.status.value}): not acted on")
        # An action clicked on an instruction a light time ago must not land on the next one.
        clicked = args.get("instruction")
        if clicked is not None and clicked != snap.current:
            return ActionAnswer(
                "REFUSED",
                f"{action.action} was for {clicked}, the run is at {snap.current or 'no instruction'}: not acted on",
            )
        perform: dict[str, Callable[[], Any]] = {
            "halt": lambda: ex.halt(user, str(args["reason"])),
            "pause": lambda: ex.pause(user),
            "continue": lambda: ex.resume_automation(user),
            "stop": lambda: ex.stop(user, str(args["reason"])),
            "perform": lambda: ex.perform(user),
            "skip": lambda: ex.skip(user, str(args["reason"])),
            "enter": lambda: ex.enter(user, args["value"]),
            "done": lambda: ex.mark_done(user),
            "confirm": lambda: ex.confirm(user),
            "approve": lambda: ex.approve(user),
            "retry": lambda: ex.retry(user),
            "replan": lambda: ex.replan(user),
            "ask_again": lambda: ex.ask_again(user),
            "resolve": lambda: ex.resolve(user, str(args["value"]), str(args["reason"])),
        }
        try:
            perform[action.action]()
        except OperatorActionError as exc:
            return ActionAnswer("REFUSED", str(exc))
        return ActionAnswer("DONE", f"{action.action} by {user}")

    def close(self) -> None:
        """Leave the runs where they are (the next start resumes them from the store) and close it.

        A run still active is not stopped: an onboard executive restarted by ``caretaker up`` picks
        it up again (:meth:`resume_interrupted`); its gateway is closed, so nothing more is sent.
        """
        with self._lock:
            runs = list(self._runs.values())
        for run in runs:
            run.gateway.close()
        self.control.close()
        self.audit.close()


def _within(path: Path, folder: Path) -> str:
    """``path``'s name within the unit's ``folder``, as the unit names its files ("" if outside)."""
    try:
        return path.resolve().relative_to(folder).as_posix()
    except ValueError:
        return ""


def _remove(folder: Path) -> None:
    """Forget a unit that was not started: its files must not make it look accepted."""
    for path in sorted(folder.rglob("*"), reverse=True):
        path.unlink() if path.is_file() else path.rmdir()
    folder.rmdir()
