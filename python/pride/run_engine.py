"""The machinery under :class:`pride.executive.Executive`: one run's state, PAX's thread, the supervisor.

:class:`RunEngine` holds the run's state under one lock, records every event in the journal
before anything else happens (:meth:`RunEngine.emit`), answers snapshots and waits, runs PAX's
thread (which performs the instructions automation or an operator asked for) and the supervisor
(links and control of the robot). It changes the state only as PAX; the operator's actions, the
start and the resume are the executive's, and :mod:`pride.executive` documents the whole
contract (the engine restores a resumed run from its log, :meth:`RunEngine.resume_from`, once the
executive found it may go on). Split so each half can be read on its own: what carries a run out,
and what people may do to it.

The executive holds one engine (it does not extend it): its public attributes (``state``,
``lock`` and ``changed``, ``control``, ``automation``, ``holdings``, ``gateway``, ``links``,
``seq``) and the guards below are what the executive's actions use, always with ``lock`` held
where they change something; observers use the executive's methods, never these.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pride.approvals import ApprovalPolicy
from pride.automation import Automation, ControlLost, InstructionResult
from pride.event_payloads import ControlLost as ControlLostRecord
from pride.event_payloads import ControlTaken, InstructionStarted, MonitorCleared, MonitorViolated, Paused, RunResumed
from pride.event_payloads import Halt as HaltRecord
from pride.events import PAX, Event, Journal, Payload
from pride.leftovers import Holdings
from pride.link_watch import LinkWatch
from pride.monitoring import MonitorChange
from pride.phrasing import fill_text, phrase
from pride.replanning import Replan, halted_motion
from pride.replay import replay
from pride.run_control import ControlStore, RunControl
from pride.run_state import RunState
from pride.states import (
    Controller,
    InstructionStatus,
    JournalFailure,
    Mode,
    OperatorActionError,
    RunEnded,
    RunStatus,
    Snapshot,
)
from pride.systems import CancelResult, LinkState, SystemGateway, TelemetryValue
from procedure_language.lint import CheckedProcedure
from procedure_language.model import Instruction

if TYPE_CHECKING:  # the release history is the ground database's: the executive only carries a run's version
    from pride.run_version import RunVersion

__all__ = ["RunEngine"]

log = logging.getLogger(__name__)

#: How long :meth:`Executive.snapshot` waits for the lock before it answers from its last state.
_SNAPSHOT_WAIT_S = 0.05
#: How often the supervisor looks at the links and at who controls the robot.
_SUPERVISE_S = 0.5


class RunEngine:
    """One run's state, journal, PAX thread and supervisor; the executive holding it adds the actions."""

    def __init__(
        self,
        checked: CheckedProcedure,
        gateway: SystemGateway,
        journal: Journal,
        *,
        run_id: str,
        mode: Mode = Mode.MANUAL,
        control: ControlStore | None = None,
        approvals: ApprovalPolicy | None = None,
        version: RunVersion | None = None,
    ) -> None:
        """Prepare a run (nothing happens until :meth:`start`).

        Args:
            checked: what to run, as :func:`procedure_language.lint.check_procedure` checked it (with its
                SysReps and sub-procedures): a procedure with errors never gets this far.
            gateway: the systems (the PAX host shape, :mod:`pride.systems`).
            journal: where every event goes first (the audit log).
            run_id: the run's id in the journal.
            mode: the initial mode.
            control: who controls which robot (the ground database); None runs without taking
                control (a bench with one run).
            approvals: which commands need a second operator's approval (the robot side's
                critical commanding, :mod:`pride.approvals`); None: off, a hazardous command
                needs its operator's confirmation only (a bench).
            version: the procedure version it runs (its release, or a rehearsal), recorded in
                ``run_started`` (:mod:`records.releases`); None: not recorded (a bench).
        """
        self.procedure = checked.procedure
        self.run_id = run_id
        self.robot = gateway.robot()
        self.checked = checked
        self.version = version
        self.gateway = gateway
        self._journal = journal
        self.control = RunControl(control, self.robot, run_id)
        self.lock = threading.RLock()  # guards every field below and the run state
        self.changed = threading.Condition(self.lock)
        self.seq = 0  # the last event's number: a resume starts after the log's
        self._listeners: list[Callable[[Event], None]] = []
        self.automation = Automation(gateway, checked, self.record, may_send=self.may_send)
        self.holdings = Holdings()  # what the run added to its systems: a stop takes it back
        self.state = RunState(
            self.procedure,
            mode,
            run_id=run_id,
            emit=self.emit,
            notify=self.changed.notify_all,
            hazardous=self.automation.is_hazardous,
            sysreps=checked.sysreps,
            holdings=self.holdings,
            approvals=approvals or ApprovalPolicy(),
        )
        self._worker: threading.Thread | None = None
        self._supervisor: threading.Thread | None = None
        self.links = LinkWatch()
        self._wake = threading.Event()  # the supervisor has something to look at
        self._reported = threading.Condition()  # telemetry changed: counted in _reports
        self._reports = 0
        self._monitored: deque[tuple[str, str, Any]] = deque()  # updates of monitored items, for the supervisor
        #: acts on a violated monitor (:func:`pride.monitoring.respond`), on a thread of its own: a halt waits
        self.on_monitor: Callable[[MonitorChange], None] | None = None
        self._halt_unrecorded = False  # a monitor's go-to waits for the record of the halt it asked for
        self._last = self._build_snapshot()
        gateway.add_listener(self._telemetry_callback)
        gateway.add_link_listener(self._link_callback)

    # ---- observation ------------------------------------------------------------------------
    def add_listener(self, callback: Callable[[Event], None]) -> None:
        """Call ``callback(event)`` for every event from now on (see the module docstring)."""
        with self.lock:
            self._listeners.append(callback)

    def remove_listener(self, callback: Callable[[Event], None]) -> None:
        with self.lock:
            self._listeners.remove(callback)

    def snapshot(self) -> Snapshot:
        """The run's state now (see the module docstring: never waits for the database)."""
        if self.lock.acquire(timeout=_SNAPSHOT_WAIT_S):
            try:
                self._last = self._build_snapshot()
            finally:
                self.lock.release()
        return self._live(self._last)

    def _build_snapshot(self) -> Snapshot:
        state = self.state
        hold, reason = state.hold()
        current = state.current_number() if state.status is RunStatus.ACTIVE else None
        pending = state.unknown[0] if state.unknown else None
        snap = Snapshot(
            run_id=self.run_id,
            procedure_id=self.procedure.id,
            status=state.status,
            mode=state.mode,
            current=current,
            hold=hold,
            reason=reason,
            executing=state.executing,
            statuses=dict(state.statuses),
            breakpoints=frozenset(state.breakpoints),
            variables=state.variables(),
            last_seq=self.seq,
            error=state.error,
            robot=self.robot,
            has_control=self.control.held and state.control_lost is None,
            unknown_key=pending,
            halted_by=state.halt.user if state.halt else None,
            halt_reason=state.halt.reason if state.halt else "",
            approval=state.approval_json(),
        )
        replan = self.halted_motion() if current is not None else None
        if replan is None:
            return snap
        return replace(snap, replan_from=replan.plan, no_retry=replan.why_not_again())

    def _live(self, snap: Snapshot) -> Snapshot:
        """``snap`` with the links and the journal as they are now (no executive lock needed)."""
        links = self.links.now()
        availability = self._journal.availability
        return replace(
            snap,
            link_lost_since=links.lost_since,
            commands_in_flight=links.in_flight,
            link_quiet=links.quiet,
            journal_available=availability.available,
            journal_unavailable_since=availability.since,
            journal_error=availability.error,
        )

    def current_instruction(self) -> Instruction | None:
        """The instruction the run is at (in the innermost sub-procedure), or None when finished."""
        place = self.current_place()
        return place[1] if place else None

    def current_place(self) -> tuple[Path, Instruction] | None:
        """The file of the (sub-)procedure the run is in and its instruction there, or None when finished."""
        with self.lock:
            frame = self.state.frame
            if self.state.status is not RunStatus.ACTIVE or frame.instruction is None:
                return None
            return Path(frame.procedure.path), frame.instruction

    def wait_for(self, predicate: Callable[[Snapshot], bool], timeout: float | None = None) -> Snapshot | None:
        """Block until ``predicate(snapshot)`` holds; return that snapshot, or None on timeout."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self.changed:
            while True:
                snap = self.snapshot()
                if predicate(snap):
                    return snap
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                self.changed.wait(remaining if remaining is not None else _SUPERVISE_S)

    def wait_for_report(self, system: str, item: str, timeout: float) -> bool:
        """Block until ``system`` reports ``item`` afresh (a value, not stale); False on timeout,
        or at once when the run ends meanwhile (stopped elsewhere: nobody needs the answer now).

        For an answer refused because the report it must be checked against was stale or missing
        (:class:`pride.states.RecordNotCheckable`): a report the link lost comes again once the
        link or the robot's bridge is back. Woken by the gateway's telemetry listener; the
        gateway is read outside that wake-up's lock (its listener thread takes the lock).
        """
        deadline = time.monotonic() + timeout
        while True:
            with self._reported:
                seen = self._reports
            try:
                reading = self.gateway.telemetry(system, item)
                if not reading.stale and reading.value is not None:
                    return True
            except Exception as exc:  # the reading failed: as stale, until the deadline says otherwise
                log.info("reading %s.%s while waiting for its report: %s", system, item, exc)
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not self.state.going_on:
                return False
            with self._reported:
                if self._reports == seen:  # nothing reported, and the run went on, since the read above
                    self._reported.wait(remaining)

    def join(self, timeout: float | None = None) -> None:
        """Wait for PAX's thread to end (after the run completed or stopped)."""
        if self._worker is not None:
            self._worker.join(timeout)
        if self._supervisor is not None:
            self._supervisor.join(timeout)

    def launch(self) -> None:
        self._worker = threading.Thread(target=self._pax_loop, name=f"pax-{self.run_id}", daemon=True)
        self._worker.start()
        self._supervisor = threading.Thread(target=self._supervise, name=f"pax-watch-{self.run_id}", daemon=True)
        self._supervisor.start()

    def resume_from(
        self,
        events: Sequence[Event],
        user: str,
        *,
        mode: Mode | None,
        take_over: str | None,
        listeners: Sequence[Callable[[Event], None]],
    ) -> None:
        """Go on, as ``user``, with the run ``events`` record (:func:`pride.replay.resumable_start`
        said it may): take control of the robot, restore the state they leave, record RUN_RESUMED
        (``listeners`` attached first) and start PAX's thread, which sends a command in flight again."""
        for event in events:
            self.holdings.note(event)
        with self.changed:
            state = self.state
            replayed = replay(self.procedure, events, self.checked.load, mode=state.mode, statuses=state.statuses)
            previous = self.control.take(user, take_over)
            state.restore(replayed)
            self.seq = replayed.seq
            if mode is not None:
                state.mode = mode
            state.status = RunStatus.ACTIVE
            self._listeners.extend(listeners)
            resumed = RunResumed(mode=state.mode.value, in_flight=state.in_flight, resend=state.resend)
            self.emit(user, state.frame.number(), resumed)
            self.record_takeover(user, previous, take_over)
            if state.frame.instruction is None:
                state.advance(state.frame.position)
            else:
                number = state.frame.number()
                if state.statuses.get(number) not in (InstructionStatus.HALTED, InstructionStatus.OUTCOME_UNKNOWN):
                    state.statuses[number] = InstructionStatus.ACTIVE
            state.announce()
            self.launch()

    # ---- guards and helpers of the executive's actions -------------------------------------------
    def require_active(self) -> None:
        """Raise RunEnded unless the run is active and no stop is under way."""
        if self.state.status is not RunStatus.ACTIVE:
            raise RunEnded(f"run {self.run_id} is {self.state.status.value}")
        if self.state.stopping:
            raise RunEnded(f"run {self.run_id} is stopping")

    def require_idle(self) -> Instruction:
        """The current instruction, if an operator may act on it now (nothing is being performed)."""
        self.require_active()
        instruction = self.state.frame.instruction
        if instruction is None:
            raise OperatorActionError("the run has no current instruction")
        if self.state.executing or self.state.request is not None:
            raise OperatorActionError(f"{self.state.current_number()} is being performed; wait for it to finish")
        return instruction

    def pending_key(self) -> str | None:
        """The key of the command whose outcome is not known (read without the lock: one attribute each)."""
        unknown = self.state.unknown
        return unknown[0] if unknown else self.state.resend

    def unknown_text(self) -> str:
        return (
            f"the outcome of {self.pending_key()} is unknown: ask again (same key), record what you found "
            "on the robot, or skip it"
        )

    def halted_motion(self) -> Replan | None:
        """The current instruction's motion if a halt ended it and used up its plan (the lock is held)."""
        state = self.state
        if state.statuses.get(state.frame.number()) is not InstructionStatus.HALTED:
            return None
        return halted_motion(state.frame, self.checked.argument)

    def clear_halt(self) -> None:
        self.state.halt = None
        self.automation.clear_halt()

    def cancel(self, key: str | None) -> CancelResult | None:
        """Cancel the command ``key`` through the gateway (None: nothing in flight); a failure is the answer."""
        if key is None:
            return None
        try:
            return self.gateway.cancel(key)
        except Exception as exc:  # the halt is still recorded, with why the cancel failed
            log.exception("cancel of %s failed", key)
            return CancelResult(False, f"cancel failed: {type(exc).__name__}: {exc}")

    # ---- control of the robot -----------------------------------------------------------------
    def record_takeover(self, user: str, previous: Controller | None, reason: str | None) -> None:
        if previous is not None:
            taken = ControlTaken(
                robot=self.robot, from_run=previous.run_id, from_user=previous.user, reason=reason or ""
            )
            self.emit(user, self.state.current_number(), taken)

    def may_send(self) -> None:
        """Raise ControlLost unless this run controls its robot (asked in the database, not remembered)."""
        lost, holder = self.control.lost()
        if lost:
            raise ControlLost(self.control.lost_text(holder), holder)

    def _lose_control(self, holder: Controller | None) -> None:
        """Another run took the robot: hold and say who (the lock is held)."""
        state = self.state
        if state.control_lost is not None or state.status is not RunStatus.ACTIVE:
            return
        state.control_lost = self.control.lost_text(holder)
        lost = ControlLostRecord(
            robot=self.robot,
            by_run=holder.run_id if holder else None,
            by_user=holder.user if holder else None,
            reason=holder.reason if holder else "",
        )
        self.emit(PAX, state.current_number(), lost)
        state.announce()

    # ---- events -----------------------------------------------------------------------------
    def emit(self, actor: str, instruction: str | None, data: Payload) -> Event:
        """Record an event (the lock is held): durably first, then wake waiters and tell listeners.

        A journal that cannot store it stops the run at once (:class:`JournalFailure`); its
        sequence number stays free for the event a resume records next.
        """
        event = Event.of(self.run_id, self.seq + 1, actor, instruction, data)
        kind = event.kind
        try:
            self._journal.append(event)  # durable first: if this raises, the action does not happen
        except Exception as exc:
            state = self.state
            state.error = f"{type(exc).__name__}: {exc}"
            state.status = RunStatus.STOPPED
            self.automation.interrupt.set()  # a watch in progress ends; nothing more is recorded
            self.changed.notify_all()
            self._report_changed()
            log.error("run %s stopped: the journal could not store %s: %s", self.run_id, kind.value, exc)
            raise JournalFailure(
                f"run {self.run_id} stopped: the audit log could not store {kind.value}: {state.error}"
            ) from exc
        self.seq = event.seq
        self.holdings.note(event)
        self._last = self._build_snapshot()  # what readers get while a later append waits for the database
        self.changed.notify_all()  # every event is a change someone may be waiting for
        if not self.state.going_on:
            self._report_changed()  # a wait for a report ends with the run
        for listener in list(self._listeners):
            try:
                listener(event)
            except Exception:  # an observer's bug must not stop a robot mid-procedure
                log.exception("event listener %r failed on %s", listener, kind.value)
        return event

    def record(self, actor: str, instruction: str | None, data: Payload) -> None:
        """Emit from PAX's thread while it does not hold the lock (automation's callback)."""
        with self.lock:
            if self.state.error is not None:
                raise JournalFailure(f"run {self.run_id} stopped: {self.state.error}")
            self.emit(actor, instruction, data)

    # ---- PAX's thread -----------------------------------------------------------------------
    def _next_job(self) -> Any:
        return None if self.automation.interrupt.is_set() else self.state.next_job()

    def _pax_loop(self) -> None:
        state = self.state
        try:
            while True:
                with self.changed:
                    job = self._next_job()
                    while job is None and state.status is RunStatus.ACTIVE:
                        self.changed.wait()
                        job = self._next_job()
                    if job is None:
                        return
                    number = state.begin(job)
                    # the sentence the procedure view shows, as written: ${...} stay references
                    text = str(phrase(job.instruction, self.checked.sysreps, job.frame.procedure))
                    filled = fill_text(text, job.frame.env)
                    started = InstructionStarted(
                        instruction_kind=job.instruction.kind.value, text=text, text_filled=filled
                    )
                    self.emit(job.actor, number, started)
                try:
                    outcome = self.automation.carry_out(
                        job.frame.env, job.frame.procedure, job.instruction, number, job.actor, job.send
                    )
                except (JournalFailure, ControlLost):
                    raise
                except KeyError as exc:
                    outcome = InstructionResult(False, str(exc.args[0]) if exc.args else str(exc))
                except Exception as exc:  # a gateway error is a failed instruction, never a success
                    log.exception("%s failed", number)
                    outcome = InstructionResult(False, f"{type(exc).__name__}: {exc}")
                with self.changed:
                    state.executing = False
                    if state.halt is None:
                        state.halt = self.automation.halt
                    state.finish(job, number, outcome)
                    if state.diverted is not None and state.going_on and not self._halt_unrecorded:
                        self._go_to_diverted()
                    if job.then_pause and state.going_on and not state.paused:
                        state.paused = True
                        self.emit(job.actor, state.current_number(), Paused(after_step=number))
                    self.changed.notify_all()
        except ControlLost as lost:
            with self.changed:
                state.executing = False
                state.statuses[state.frame.number()] = InstructionStatus.ACTIVE
                self._lose_control(lost.holder)
            self._pax_loop()  # nothing was sent: carry on waiting (the hold keeps automation back)
        except JournalFailure:
            pass  # the run stopped in _emit, with the journal's reason
        except Exception as exc:  # a bug must not leave a run looking alive
            log.exception("run %s stopped: %s", self.run_id, exc)
            with self.changed:
                state.error = f"{type(exc).__name__}: {exc}"
                state.status = RunStatus.STOPPED
                state.executing = False
                self.automation.interrupt.set()
                self.changed.notify_all()
        finally:
            self._wake.set()

    # ---- the supervisor: links and control, on its own thread -----------------------------------
    def _supervise(self) -> None:
        """Record link changes and notice a takeover of the robot until the run ends; then release it."""
        try:
            while self.state.status is RunStatus.ACTIVE:
                self._wake.wait(_SUPERVISE_S)
                self._wake.clear()
                change = self.links.change()
                lost, holder = self.control.lost() if self.state.control_lost is None else (False, None)
                updates = [self._monitored.popleft() for _ in range(len(self._monitored))]
                if change is None and not lost and not updates:
                    continue
                with self.changed:
                    if change is not None and self.state.status is RunStatus.ACTIVE:
                        self.emit(PAX, self.state.current_number(), change)
                    if lost:
                        self._lose_control(holder)
                    violated = self._watch_monitors(updates)
                for monitor in violated:  # a halt waits for the robot's answer: never on this thread
                    threading.Thread(target=self.on_monitor, args=(monitor,), name="pax-monitor", daemon=True).start()
        except JournalFailure:
            pass  # the run stopped in _emit, with the journal's reason
        except Exception:
            log.exception("run %s: watching links and control failed", self.run_id)
        finally:
            if self.state.status is not RunStatus.ACTIVE:
                self.control.release()

    def _link_callback(self, state: LinkState) -> None:
        """Called by the gateway on its own thread: note the link, let the supervisor record it."""
        self.links.update(state)
        self._wake.set()

    def _telemetry_callback(self, sysrep_id: str, item_id: str, value: TelemetryValue) -> None:
        """Called by the gateway on its own thread when telemetry changes: wake any watcher, and the
        supervisor when a monitor reads the item."""
        self.automation.telemetry_changed.set()
        if self.state.monitors.watches(sysrep_id, item_id):
            self._monitored.append((sysrep_id, item_id, value.value))
            self._wake.set()
        self._report_changed()

    def _watch_monitors(self, updates: list[tuple[str, str, Any]]) -> list[MonitorChange]:
        """Record what the monitors made of ``updates`` (the lock is held); the violations to act on."""
        violated: list[MonitorChange] = []
        for system, item, value in updates:
            if self.state.status is not RunStatus.ACTIVE:
                break
            for change in self.state.monitors.update(system, item, value):
                monitor = change.monitor
                if change.violated:
                    action = monitor.on_violation + (f":{monitor.goto}" if monitor.goto else "")
                    payload: Payload = MonitorViolated(
                        monitor=monitor.name,
                        system=system,
                        telemetry=item,
                        value=value,
                        limit=change.limit,
                        action=action,
                        text=monitor.describe(),
                    )
                else:
                    payload = MonitorCleared(monitor=monitor.name, system=system, telemetry=item, value=value)
                self.emit(PAX, self.state.current_number(), payload)
                if change.violated and monitor.on_violation == "hold":  # with the violation, before anything moves on
                    if not self.state.paused:
                        self.state.paused = True
                        self.emit(PAX, self.state.current_number(), Paused())
                elif change.violated:
                    violated.append(change)
        return violated if self.on_monitor is not None else []

    def divert(self, step: str, reason: str) -> bool:
        """A monitor's go-to: the run goes to ``step`` once what is in progress ended (True: it must be
        halted first), at once if nothing is (False)."""
        with self.changed:
            if not self.state.going_on:
                return False
            self.state.diverted = (step, reason)
            if self.state.executing:
                self._halt_unrecorded = True
                return True
            self._go_to_diverted()
            return False

    def record_halt(self, user: str, halted: HaltRecord) -> None:
        """Record a halt (the lock is held). A monitor's go-to waits for it: the robot answers a halt
        once the motion stopped, and the run, gone on to a contingency that nothing holds, could have
        ended by then with the halt never on its record. It goes now if what it halted has ended."""
        self.emit(user, self.state.current_number(), halted)
        self._halt_unrecorded = False
        if self.state.diverted is not None and self.state.going_on and not self.state.executing:
            self._go_to_diverted()

    def _go_to_diverted(self) -> None:
        step, reason = self.state.diverted or ("", "")
        self.state.diverted = None
        self.automation.clear_halt()  # the halt that stopped the motion ends here: the run goes on there
        self.state.go_to(step, PAX, reason)
        self.changed.notify_all()

    def _report_changed(self) -> None:
        """Wake :meth:`wait_for_report`: telemetry came, or the run ended."""
        with self._reported:
            self._reports += 1
            self._reported.notify_all()
