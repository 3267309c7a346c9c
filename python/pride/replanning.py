"""After a halted motion the way on is to plan it again from where the arm is, not to send it again.

A motion system plans a motion, then executes the stored plan once: the AT server's
``execute_plan`` runs the plan ``plan_trajectory`` made for the same template instance and
trajectory, and uses it up. A halt mid-motion leaves the arm off the plan's start and the server
drops the plan, so after a halted ``execute_plan`` neither a retry nor "continue" can work (the
server refuses: no valid plan). What can work is going back to the instruction that planned the
motion: it plans again from where the arm is now (the AT server plans the rest of a halted
trajectory), and the run goes on from there, performing again what lies between (the plan's
check, the operator's confirmation that the area is clear).

Each :class:`PlannedMotion` says which SysRep command plans a motion, which one executes it, and
which arguments name the motion in both; another system with plans used up by their execution is
one more entry in :data:`MOTIONS`. :func:`halted_motion` finds, for a halted instruction, the
instruction of its step that plans it again (:class:`Replan`); the executive offers that as the
operator's way on and refuses a retry or continue that cannot work
(:meth:`pride.executive.Executive.replan`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pride.frames import Frame
from procedure_language.model import ArgumentBinding, CommandInstruction

__all__ = ["MOTIONS", "PlannedMotion", "Replan", "halted_motion"]

#: How a run finds a command argument's value in its variables
#: (:meth:`procedure_language.lint.CheckedProcedure.argument`).
Argument = Callable[[ArgumentBinding, dict[str, Any]], Any]


@dataclass(frozen=True)
class PlannedMotion:
    """A motion a system plans with one command and executes once with another."""

    system: str  # the SysRep (the procedure's ``system=``)
    plans: str  # the command that plans the motion
    executes: str  # the command that executes the stored plan, using it up
    names: tuple[str, ...]  # the arguments that name one motion in both, in the order words name it


#: The AT SysRep's motions: a trajectory of a template instance ("grasp_and_pull of cdra_filter:0").
MOTIONS: tuple[PlannedMotion, ...] = (
    PlannedMotion("affordance_templates", "plan_trajectory", "execute_plan", ("trajectory", "affordance_template")),
)


@dataclass(frozen=True)
class Replan:
    """A halted motion, whose plan ended with the halt, and the instruction that plans it again."""

    halted: str  # the halted instruction's number
    motion: str  # the motion in words, e.g. "grasp_and_pull of cdra_filter:0"
    plan: str | None = None  # the number of the instruction of its step that plans it, None if there is none
    position: int | None = None  # that instruction's position in the frame

    def why_not_again(self) -> str:
        """Why sending the halted motion again cannot work, and what can (the operator's words)."""
        if self.plan is None:
            way = "go back to an instruction that plans it, skip it or stop the run"
        else:
            way = f"re-plan from where the arm is ({self.plan}) and go on"
        return f"{self.halted} cannot be sent again: the plan of {self.motion} ended with the halt; {way}"

    def reason(self) -> str:
        """The recorded reason of going back to re-plan."""
        return f"re-plan {self.motion} from where the arm is and go on ({self.halted} was halted)"


def halted_motion(frame: Frame, argument: Argument) -> Replan | None:
    """The motion of the frame's current instruction, known by the caller to be halted, with the
    instruction before it in its step that plans the same motion; None when it executes no planned
    motion (a retry of anything else is a new attempt that can work)."""
    instruction = frame.instruction
    if not isinstance(instruction, CommandInstruction):
        return None
    motion = next((m for m in MOTIONS if (m.system, m.executes) == (instruction.system, instruction.command)), None)
    if motion is None:
        return None
    named = _named(motion, instruction, frame.env, argument)
    if named is None:  # it was sent with these values: they resolve unless a record was corrected away
        return None
    words = " of ".join(str(value) for value in named)
    procedure = frame.procedure
    step = procedure.step_of(instruction.number)
    for position in range(frame.position - 1, -1, -1):
        earlier = procedure.instructions[position]
        if procedure.step_of(earlier.number) is not step:
            break
        if (
            isinstance(earlier, CommandInstruction)
            and (earlier.system, earlier.command) == (motion.system, motion.plans)
            and _named(motion, earlier, frame.env, argument) == named
        ):
            return Replan(frame.number(), words, frame.number(position), position)
    return Replan(frame.number(), words)


def _named(
    motion: PlannedMotion, instruction: CommandInstruction, env: dict[str, Any], argument: Argument
) -> tuple[Any, ...] | None:
    """The values of the arguments that name the motion, as the run knows them now (None if it cannot)."""
    bindings = {binding.name: binding for binding in instruction.args}
    try:
        return tuple(argument(bindings[name], env) for name in motion.names)
    except KeyError:  # a value not bound (yet): it names no motion of this run
        return None
