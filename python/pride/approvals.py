"""Critical commanding: a command that can do harm is sent only once a second operator approved it.

Why: one operator's slip (a wrong field, a command sent to the wrong robot) should not reach the
habitat alone. As in COSMOS's Critical Commanding, the *level* of a robot side (its deployment's
``critical_commanding:``, read on the ground by :mod:`pride.robot_sides`) says which commands need
it: ``off`` (a hazardous command needs only its operator's own confirmation, as before),
``hazardous`` (a command the SysRep or the procedure marks hazardous needs a second operator's
approval; the default) or ``all`` (every command does).

The flow (the executive's ``confirm`` and ``approve``): the operator who would send the command
asks for it to be sent (the *sender*: "Send" in manual mode, "Send for approval" at the hold of an
autonomous run); every console shows the request with the command in words; a different signed-in
operator approves it (the sender's own approval is refused with the reason), and then it is sent
at once, the sender and the approver both in its ``command_sent`` record. An approval is good for
``approval_expires_s`` (default five minutes): a command that could not be sent in that time (the
run paused, a breakpoint, the link) is never sent on it; the run records that it expired and waits
for a new approval.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

from datafile import Field
from pride.lint import CheckedProcedure
from pride.model import CommandInstruction, Instruction
from pride.sysrep import SysRep

__all__ = [
    "DEFAULT_EXPIRY_S",
    "Approval",
    "ApprovalPolicy",
    "ApprovalRequest",
    "CriticalLevel",
    "command_hazardous",
    "onboard_refusal",
    "policy_from",
    "self_approval_refusal",
]

#: How long an approval stays good when the deployment does not say (s): long enough for the
#: sender to see it land, short enough that nobody sends on yesterday's judgement.
DEFAULT_EXPIRY_S = 300.0


class CriticalLevel(str, enum.Enum):
    """Which commands need a second operator's approval before they are sent."""

    OFF = "off"
    """None: a hazardous command needs only its operator's confirmation."""
    HAZARDOUS = "hazardous"
    """Commands marked hazardous (in the SysRep or the procedure)."""
    ALL = "all"
    """Every command."""


def _utc_now() -> datetime:
    return datetime.now(UTC)


@dataclass(frozen=True)
class ApprovalPolicy:
    """The level of a robot side and how long an approval stays good; ``clock`` tells the time
    (injectable so the expiry is tested without waiting)."""

    level: CriticalLevel = CriticalLevel.OFF
    expires_s: float = DEFAULT_EXPIRY_S
    clock: Callable[[], datetime] = field(default=_utc_now, compare=False, repr=False)

    def needs_approval(self, is_command: bool, hazardous: bool) -> bool:
        """Whether a second operator must approve this instruction before it is sent."""
        if not is_command or self.level is CriticalLevel.OFF:
            return False
        return self.level is CriticalLevel.ALL or hazardous

    def describe(self) -> str:
        """ "hazardous commands need a second operator's approval (good for 300 s)", for messages."""
        if self.level is CriticalLevel.OFF:
            return "critical commanding is off"
        which = "every command needs" if self.level is CriticalLevel.ALL else "hazardous commands need"
        return f"{which} a second operator's approval (good for {self.expires_s:g} s)"


@dataclass(frozen=True)
class ApprovalRequest:
    """A sender asked for the current command to be sent: it waits for a second operator."""

    number: str
    sender: str
    asked: datetime
    command: str  # the command in words, as consoles show it


@dataclass(frozen=True)
class Approval:
    """A second operator approved the request; good until ``expires``."""

    request: ApprovalRequest
    approver: str
    approved: datetime
    expires: datetime

    @classmethod
    def given(cls, request: ApprovalRequest, approver: str, policy: ApprovalPolicy) -> Approval:
        now = policy.clock()
        return cls(request, approver, now, now + timedelta(seconds=policy.expires_s))

    def stale(self, now: datetime) -> bool:
        return now >= self.expires


def command_hazardous(instruction: Instruction, sysreps: Mapping[str, SysRep]) -> bool:
    """Whether an instruction is a hazardous command: marked so in the procedure, or in its SysRep."""
    if not isinstance(instruction, CommandInstruction):
        return False
    sysrep = sysreps.get(instruction.system)
    command = sysrep.command(instruction.command) if sysrep is not None else None
    return instruction.hazardous or bool(command is not None and command.hazardous)


def onboard_refusal(checked: CheckedProcedure, policy: ApprovalPolicy) -> str | None:
    """Why a procedure may not run onboard under ``policy`` (None: it may).

    Approvals of an onboard run would have to be collected on the ground before the unit goes up
    and carried with it, signed; that is not built yet, so a procedure with a command that needs
    approval runs from the ground, where every console can approve it.
    """
    needing = [
        f"{instruction.number} {instruction.command}" if where == "" else f"{instruction.command} in {where}"
        for where, procedure in (("", checked.procedure), *((Path(p).name, c) for p, c in checked.callees.items()))
        for instruction in procedure.instructions
        if policy.needs_approval(
            isinstance(instruction, CommandInstruction), command_hazardous(instruction, checked.sysreps)
        )
        and isinstance(instruction, CommandInstruction)
    ]
    if not needing:
        return None
    return (
        f"{', '.join(needing)} need{'s' if len(needing) == 1 else ''} a second operator's approval "
        f"({policy.describe()}), and approvals are not carried to the habitat yet: run it from the ground"
    )


def self_approval_refusal(request: ApprovalRequest, approver: str) -> str | None:
    """Why ``approver`` may not approve ``request`` (None: they may): nobody approves their own send."""
    if approver != request.sender:
        return None
    return (
        f"{approver} asked for {request.number} to be sent: a second operator must approve it, "
        f"not {approver} (nobody approves their own command)"
    )


def policy_from(f: Field | None) -> ApprovalPolicy:
    """A deployment's ``critical_commanding:`` (absent: hazardous commands need approval, the
    default expiry): ``{level: off|hazardous|all, approval_expires_s: S}``, or the level alone."""
    if f is None:
        return ApprovalPolicy(CriticalLevel.HAZARDOUS)
    if f.node.kind != "mapping":
        return ApprovalPolicy(_level(f))
    f.mapping(required=("level",), optional=("approval_expires_s",))
    expires = f["approval_expires_s"].number(min=1.0, max=86400.0) if f.has("approval_expires_s") else DEFAULT_EXPIRY_S
    return ApprovalPolicy(_level(f["level"]), expires)


def _level(f: Field) -> CriticalLevel:
    if f.node.value is False:  # YAML reads a bare off as false
        return CriticalLevel.OFF
    return CriticalLevel(f.choice([level.value for level in CriticalLevel]))
