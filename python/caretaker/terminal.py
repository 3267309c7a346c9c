"""The runner's terminal: progress step by step, and the operator's answers when PAX holds.

:class:`ProgressPrinter` is an executive listener (it only prints). :class:`OperatorConsole`
answers holds on the main thread: from ``--set``/``--confirm-*`` options for unattended runs
(recorded under the runner's user), else by prompting when stdin is a terminal, else it stops
the run and says which option would have answered.
"""

from __future__ import annotations

import getpass
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TextIO, assert_never

from pride import event_payloads as ep
from pride.event_words import describe_event, result_text, started_text, telemetry_text
from pride.events import Event
from pride.executive import Executive, Hold, InstructionStatus, Mode, OperatorActionError, Snapshot
from pride.phrasing import Wording
from pride.states import RecordNotCheckable, RunEnded
from procedure_language.model import Procedure, RecordInstruction

__all__ = ["LeftBehind", "OperatorConsole", "ProgressPrinter", "TerminalLines", "Unattended"]

#: How long an unattended run waits at one instruction for a report its answer must be checked
#: against (stale after a lost link or a restarted bridge: the robot's bridge is restarted and
#: reconnected within this, then the report crosses the link again), before it stops the run.
REPORT_WAIT_S = 120.0
#: A command's outcome as the terminal marks it (short, the failures in capitals to stand out).
_MARKS = {"succeeded": "ok", "failed": "FAILED", "unknown": "OUTCOME UNKNOWN", "halted": "HALTED"}


class TerminalLines:
    """Whole lines to one stream from several threads.

    The executive's listener, the operator console and the runner's READY line print from
    different threads, and ``print`` writes the text and its newline in two calls: without one
    lock, a READY line could end in the next step's header, and a reader waiting for
    ``READY run <id>`` would take the header for part of the run id.
    """

    def __init__(self, stream: TextIO = sys.stdout) -> None:
        self.stream = stream
        self._lock = threading.Lock()

    def say(self, text: str) -> None:
        """Write ``text`` and a newline as one unit, and flush (a reader waits on whole lines)."""
        with self._lock:
            self.stream.write(text + "\n")
            self.stream.flush()


class ProgressPrinter:
    """Prints one line per meaningful event, with a header when a new step begins.

    Commands, results, readings and records read as in the audit panel and the report
    (:mod:`pride.phrasing`, with ``wording``'s SysRep labels); the call as sent only with
    ``wording.raw`` (``caretaker run --raw``).
    """

    def __init__(self, procedure: Procedure, out: TerminalLines, wording: Wording | None = None) -> None:
        self.procedure = procedure
        self.out = out
        self.wording = wording or Wording()
        self._step: str | None = None

    def __call__(self, event: Event) -> None:
        number = event.instruction or ""
        who = f"  {number:<8} {event.actor:<10}"  # an operator's or PAX's action at the instruction
        pax = f"  {number:<8} {'PAX':<10}"
        line: str | None = None
        match event.data:
            case ep.RunStarted() as d:
                line = f"Run {event.run_id}: {d.title} (v{d.version}) by {event.actor}, {d.mode} mode"
            case ep.RunResumed() as d:
                line = f"Run {event.run_id} resumed by {event.actor} at {number}, {d.mode} mode"
            case ep.InstructionStarted():
                self._header(number)
                line = f"{who} {started_text(event)}"
            case ep.CommandSent() as d:
                line = f"{who} {describe_event(event, self.wording)}" + (f" [{d.key}]" if d.key else "")
            case ep.CommandResult() as d:
                line = f"  {number:<8} {'':<10} {result_text(d, self.wording, _MARKS)}"
            case ep.Halt() as d:
                told = d.cancel_message
                line = f"{who} HALT{_why(d.reason)}" + (f"; the system: {told}" if told else "")
            case ep.InstructionHalted() as d:
                line = f"{who} halted before it finished{_why(d.reason)}"
            case ep.LinkLost() as d:
                n = d.in_flight
                line = (
                    f"{pax} {'no news' if d.quiet else 'link lost'} since {d.since[11:19]}Z, {n} command"
                    f"{'' if n == 1 else 's'} in flight{': waiting for it' if n else ''}"
                )
            case ep.LinkRestored() as d:
                line = f"{pax} link restored after {d.seconds:g} s"
            case ep.ControlTaken() as d:
                line = f"{who} took control of {d.robot} from run {d.from_run} ({d.from_user}){_why(d.reason)}"
            case ep.ControlLost() as d:
                line = f"{pax} control of {d.robot} taken over by {d.by_user} (run {d.by_run}){_why(d.reason)}"
            case ep.OperatorInput():
                self._header(number)  # a correction, below, may be of an earlier step's record
                line = f"{who} {describe_event(event, self.wording)}"
            case ep.RecordCorrected():
                line = f"{who} {describe_event(event, self.wording)}"
            case ep.SteppedBack() as d:
                line = f"{who} back to {d.next}{_why(d.reason)}"
            case ep.OutcomeResolved() as d:
                line = f"{who} recorded {d.key} as {d.outcome}{_why(d.reason)}"
            case ep.TelemetrySeen() as d:
                line = f"  {number:<8} {'':<10} {telemetry_text(d, self.wording)}"
            case ep.InstructionCompleted() as d:
                line = f"{who} done" + (f", go to step {d.went_to}" if d.went_to else "")
            case ep.InstructionFailed() as d:
                branch = f"; branching to step {d.branch}" if d.branch else ""
                line = f"{who} FAILED: {d.reason}{branch}"
            case ep.InstructionSkipped() as d:
                line = f"{who} skipped: {d.reason}"
            case ep.AwaitingOperator() as d:
                self._header(number)
                line = f"{pax} waiting for an operator: {d.reason}"
            case (
                ep.ActionRefused() | ep.SupervisorAttached() | ep.MonitorViolated() | ep.MonitorCleared() | ep.WentTo()
            ):
                line = f"{who} {describe_event(event, self.wording)}"
            case ep.Retry(same_key=True) as d:
                line = f"{who} asked again about {d.key} (same key)"
            case ep.ModeChanged() as d:
                line = f"{who} mode changed {d.mode}"
            case (
                ep.Confirmation() | ep.Paused() | ep.Continued() | ep.BreakpointHit() | ep.Retry() | ep.BreakpointSet()
            ):
                line = f"{who} {event.kind.value.replace('_', ' ')}"
            case ep.RunCompleted():
                line = f"Run {event.run_id} completed" + ("" if event.actor == "PAX" else f" by {event.actor}")
            case ep.RunStopped() as d:
                line = f"Run {event.run_id} stopped by {event.actor}" + (f": {d.reason}" if d.reason else "")
            case (
                ep.CallEntered()
                | ep.ValueSet()
                | ep.CallReturned()
                | ep.BreakpointCleared()
                | ep.ApprovalRequested()
                | ep.ApprovalGiven()
                | ep.ApprovalExpired()
            ):
                pass  # the lines around them say enough
            case _:
                assert_never(event.data)
        if line is not None:
            self.out.say(line)

    def _header(self, number: str) -> None:
        top = number.split(".")[0]
        if top != self._step and top.isdigit():
            self._step = top
            step = self.procedure.steps[int(top) - 1]
            self.out.say(f"Step {step.number}  {step.title}")


def _why(reason: str) -> str:
    return f": {reason}" if reason else ""


class _Superseded(Exception):
    """The run changed while the operator was typing (a halt, another console): the answer is not applied."""


@dataclass
class Unattended:
    """Answers given on the command line for a run nobody watches."""

    values: dict[str, str] = field(default_factory=dict)
    confirm_manual: bool = False
    confirm_hazardous: bool = False
    in_flight: str | None = None  # "resend" | "skip"
    approver: str | None = None  # a second operator (--approver, checked at the start) who approves


class OperatorConsole:
    """Answers the executive's holds as ``user``, until the run ends."""

    def __init__(
        self,
        executive: Executive,
        user: str,
        answers: Unattended,
        *,
        interactive: bool,
        out: TerminalLines,
        read: Callable[[str], str] = input,
        read_secret: Callable[[str], str] = getpass.getpass,
        second_operator: Callable[[str, str], str] | None = None,
    ) -> None:
        """``second_operator(user, password)``: that second operator's user id once their
        password checks out (ValueError says why not), so one can approve at this terminal."""
        self.executive = executive
        self.user = user
        self.answers = answers
        self.interactive = interactive
        self.out = out
        self._read = read
        self._read_secret = read_secret
        self._second_operator = second_operator
        self._answering: Snapshot | None = None
        self._report_waits: dict[str, float] = {}  # instruction: when its answer was first refused as uncheckable
        self._interrupts = 0

    def run(self) -> Snapshot:
        """Block until the run completes or stops; return its last snapshot."""
        while True:
            snap = self.executive.wait_for(lambda s: s.status.value != "active" or s.hold is not None)
            assert snap is not None
            if snap.status.value != "active":
                return snap
            self._answering = snap
            try:
                self._answer(snap)
            except _Superseded:
                continue
            except RecordNotCheckable as exc:
                self._say(f"  not accepted: {exc}")
                if not self.interactive and not self._await_report(snap, exc):
                    self._stop(str(exc))
            except RunEnded as exc:  # ended elsewhere while this terminal answered: the wait above returns it
                self._say(f"  not accepted: {exc}")
            except OperatorActionError as exc:
                self._say(f"  not accepted: {exc}")
                if not self.interactive:
                    self._stop(str(exc))

    def _stop(self, reason: str) -> None:
        """Stop the run unattended, unless another console or host ended it (or is ending it) first."""
        try:
            self.executive.stop(self.user, reason)
        except RunEnded as exc:
            self._say(f"  not stopped here: {exc}")

    def _await_report(self, snap: Snapshot, refused: RecordNotCheckable) -> bool:
        """Unattended, an answer that could not be checked now is given again once the system
        reports afresh, for up to :data:`REPORT_WAIT_S` at one instruction; whether it reported."""
        since = self._report_waits.setdefault(snap.current or "", time.monotonic())
        remaining = REPORT_WAIT_S - (time.monotonic() - since)
        if remaining <= 0:
            return False
        self._say(f"  waiting up to {remaining:.0f} s for {refused.system} to report {refused.item} afresh")
        return self.executive.wait_for_report(refused.system, refused.item, remaining)

    def interrupt(self) -> None:
        """Ctrl-C: the first halts the robot and holds the run, the next stops the run.

        Called from the signal handler: the halt runs on its own thread, so the handler returns at
        once and never re-enters the executive from inside an action the main thread is taking.
        """
        self._interrupts += 1
        first = self._interrupts == 1

        def act() -> None:  # prints here, not in the handler: it may have interrupted a print
            if first:
                self._say("\n  HALT (Ctrl-C): stopping the robot and holding the run; Ctrl-C again stops the run")
            else:
                self._say("\n  STOP (Ctrl-C twice): the run stops (resume it with --resume)")
            try:
                if first:
                    self.executive.halt(self.user, "Ctrl-C at the terminal")
                else:
                    self.executive.stop(self.user, "Ctrl-C twice at the terminal")
            except OperatorActionError as exc:
                self._say(f"  not accepted: {exc}")

        threading.Thread(target=act, name="terminal-interrupt", daemon=True).start()

    def _say(self, text: str) -> None:
        self.out.say(text)

    def _unattended_stop(self, snap: Snapshot, option: str) -> None:
        self._say(f"  {snap.reason}\n  nobody at the terminal to answer: {option}")
        self._stop(f"unattended run needs an operator at {snap.current}: {snap.reason}")

    def _answer(self, snap: Snapshot) -> None:
        ex, user, hold = self.executive, self.user, snap.hold
        instruction = ex.current_instruction()
        if hold is Hold.OPERATOR_INPUT and isinstance(instruction, RecordInstruction):
            if instruction.name in self.answers.values:
                ex.enter(user, self.answers.values[instruction.name])
            elif self.interactive:
                self._notices(instruction)
                answer = self._ask(f"{snap.reason} ({instruction.type}) > ")  # its text, values filled in
                if answer == "!skip":
                    ex.skip(user, self._ask("reason > "))
                else:
                    ex.enter(user, answer)
            else:
                self._unattended_stop(snap, f"pass --set {instruction.name}=VALUE")
        elif hold is Hold.OPERATOR_ACTION:
            if self.answers.confirm_manual:
                ex.mark_done(user)
            elif self.interactive:
                self._notices(instruction)
                self._choose(snap, {"": ("done", lambda: ex.mark_done(user))})
            else:
                self._unattended_stop(snap, "pass --confirm-manual to mark manual instructions done")
        elif hold is Hold.CONFIRMATION:
            approval = snap.approval is not None
            if self.answers.confirm_hazardous:
                ex.confirm(user)
            elif self.interactive:
                self._notices(instruction)
                label = "send it for a second operator's approval" if approval else "confirm and send"
                self._choose(snap, {"y": (label, lambda: ex.confirm(user))})
            else:
                todo = "send it for a second operator's approval" if approval else "confirm hazardous commands"
                self._unattended_stop(snap, f"pass --confirm-hazardous to {todo}")
        elif hold is Hold.APPROVAL:
            if self.answers.approver is not None:
                ex.approve(self.answers.approver)
            elif self.interactive and self._second_operator is not None:
                self._choose(snap, {"a": ("a second operator approves it here", self._approve_here)})
            else:
                self._unattended_stop(
                    snap,
                    "waiting for a second operator's approval: give --approver USER (a second operator; their "
                    "password in $CARETAKER_APPROVER_PASSWORD)",
                )
        elif hold is Hold.OUTCOME_UNKNOWN:
            if self.interactive:
                check = "what did you check on the robot? > "
                self._choose(
                    snap,
                    {
                        "a": ("ask again (same key)", lambda: ex.ask_again(user)),
                        "y": ("record: it succeeded", lambda: ex.resolve(user, "succeeded", self._ask(check))),
                        "n": ("record: it failed", lambda: ex.resolve(user, "failed", self._ask(check))),
                    },
                )
            else:
                self._unattended_stop(snap, "resume the run (it asks the habitat again), or at a terminal decide")
        elif hold is Hold.HALTED:
            if self.interactive:
                halted_here = snap.statuses.get(snap.current or "") is InstructionStatus.HALTED
                carry_on = (
                    ("r", ("retry", lambda: ex.retry(user)))
                    if halted_here
                    else ("c", ("continue", lambda: ex.resume_automation(user)))
                )
                # after a halted motion its plan ended with it: only re-planning from where the arm is can go on
                ways = {} if snap.no_retry else dict([carry_on])
                if snap.replan_from:
                    ways["p"] = (
                        f"re-plan from where the arm is and go on (from {snap.replan_from})",
                        lambda: ex.replan(user),
                    )
                if snap.no_retry:
                    self._say(f"  {snap.no_retry}")
                self._choose(snap, ways)
            else:
                self._unattended_stop(snap, "resume the run at a terminal to retry, continue or skip")
        elif hold is Hold.CONTROL_LOST:
            if self.interactive:
                self._choose(snap, {"t": ("take control back", lambda: ex.take_control(user, self._ask("reason > ")))})
            else:
                self._unattended_stop(snap, "another run controls the robot now")
        elif hold is Hold.IN_FLIGHT:
            if self.answers.in_flight == "resend":
                self._resend(snap, instruction)
            elif self.answers.in_flight == "skip":
                ex.skip(user, "in flight when the runner stopped; operator chose not to resend (--in-flight skip)")
            elif self.interactive:
                self._choose(snap, {"r": ("resend", lambda: ex.retry(user))})
            else:
                self._unattended_stop(snap, "pass --in-flight resend or --in-flight skip")
        elif hold is Hold.FAILURE:
            if self.interactive:
                self._choose(snap, {"r": ("retry", lambda: ex.retry(user))})
            else:
                self._unattended_stop(snap, "resume the run at a terminal to retry or skip it")
        elif hold in (Hold.MANUAL_MODE, Hold.NOT_AUTOMATABLE):
            if self.interactive:
                self._notices(instruction)
                self._choose(
                    snap,
                    {
                        "": ("perform", lambda: ex.perform(user)),
                        "a": ("switch to autonomous", lambda: ex.set_mode(user, Mode.AUTONOMOUS)),
                    },
                )
            else:
                self._unattended_stop(snap, "run with --auto, or at a terminal")
        elif hold in (Hold.BREAKPOINT, Hold.PAUSED):
            if self.interactive:
                self._choose(
                    snap, {"c": ("continue", lambda: ex.resume_automation(user)), "n": ("step", lambda: ex.step(user))}
                )
            else:
                ex.resume_automation(user)

    def _approve_here(self) -> None:
        """A second operator approves at this terminal with their own user and password."""
        assert self._second_operator is not None
        who = self._ask("second operator's user > ").strip()
        try:
            approver = self._second_operator(who, self._read_secret(f"{who}'s password > "))
        except ValueError as exc:
            self._say(f"  not approved: {exc}")
            return
        self.executive.approve(approver)

    def _resend(self, snap: Snapshot, instruction: Any) -> None:
        if self.executive.is_hazardous(instruction):
            if not self.answers.confirm_hazardous:
                self._unattended_stop(snap, "the in-flight command is hazardous: add --confirm-hazardous to resend it")
                return
            self.executive.confirm(self.user)
        self.executive.retry(self.user)

    def _notices(self, instruction: Any) -> None:
        for notice in getattr(instruction, "notices", ()):
            self._say(f"  {notice.level.upper()}: {notice.text}")

    def _choose(self, snap: Snapshot, options: dict[str, tuple[str, Any]]) -> None:
        menu = ", ".join(f"[{key or 'Enter'}] {label}" for key, (label, _) in options.items())
        answer = self._ask(f"{snap.reason}\n  {menu}, [s] skip, [q] stop > ").strip().lower()
        if answer in options:
            options[answer][1]()
        elif answer == "s":
            self.executive.skip(self.user, self._ask("reason > ") or "skipped at the terminal")
        elif answer == "q":
            self.executive.stop(self.user, self._ask("reason > ") or "stopped at the terminal")
        else:
            self._say(f"  unknown answer {answer!r}")

    def _ask(self, prompt: str) -> str:
        try:
            answer = self._read(prompt)
        except EOFError:
            self.executive.stop(self.user, "terminal closed")
            return ""
        now, was = self.executive.snapshot(), self._answering
        if was is not None and (now.status, now.current, now.hold) != (was.status, was.current, was.hold):
            self._say(f"  the run changed meanwhile ({now.reason or now.status.value}): that answer is not applied")
            raise _Superseded
        return answer


class LeftBehind:
    """An executive listener: once the run ends, one ``LEFT`` line per thing it left on a system.

    A stopped run takes back the Affordance Template instances it added; what it could not (a
    removal failed, the link was lost, an outcome is not known) or a completed procedure did not
    remove is listed in the end event (:mod:`pride.leftovers`). Said here too, so an operator at
    the terminal sees what to clean up without reading the report.
    """

    def __init__(self, out: TerminalLines) -> None:
        self.out = out

    def __call__(self, event: Event) -> None:
        if isinstance(event.data, (ep.RunStopped, ep.RunCompleted)):
            for system, name, why in event.data.leftovers():
                self.out.say(f"LEFT {name} on {system}: {why}")
