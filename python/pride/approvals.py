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

An onboard run cannot wait a round trip for each approval: its approvals are given on the ground
before the unit goes up and carried in it, signed with the unit (:class:`CarriedApproval`).
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

from datafile import Field
from pride.event_payloads import ApprovalExpired
from procedure_language.lint import CheckedProcedure
from procedure_language.model import CommandInstruction, Instruction
from procedure_language.sysrep import SysRep

__all__ = [
    "APPROVER_PASSWORD_ENV",
    "DEFAULT_EXPIRY_S",
    "Approval",
    "ApprovalPoint",
    "ApprovalPolicy",
    "ApprovalRequest",
    "CarriedApproval",
    "CriticalLevel",
    "approval_points",
    "command_hazardous",
    "command_name",
    "missing_approvals_text",
    "policy_from",
    "self_approval_refusal",
]

#: How long an approval stays good when the deployment does not say (s): long enough for the
#: sender to see it land, short enough that nobody sends on yesterday's judgement.
DEFAULT_EXPIRY_S = 300.0
#: Where a runner started unattended (``caretaker run --approver USER``, or by a console for an
#: onboard unit) finds the approver's password: never on a command line, where the host shows it.
APPROVER_PASSWORD_ENV = "CARETAKER_APPROVER_PASSWORD"


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

    def expiry_record(self) -> ApprovalExpired:
        """What an ``approval_expired`` event records of it."""
        request = self.request
        return ApprovalExpired(
            approver=self.approver, sender=request.sender, command=request.command, expired=self.expires.isoformat()
        )


def command_hazardous(instruction: Instruction, sysreps: Mapping[str, SysRep]) -> bool:
    """Whether an instruction is a hazardous command: marked so in the procedure, or in its SysRep."""
    if not isinstance(instruction, CommandInstruction):
        return False
    sysrep = sysreps.get(instruction.system)
    command = sysrep.command(instruction.command) if sysrep is not None else None
    return instruction.hazardous or bool(command is not None and command.hazardous)


def command_name(instruction: CommandInstruction) -> str:
    """ "system.command": how an approval names the command it covers."""
    return f"{instruction.system}.{instruction.command}"


@dataclass(frozen=True)
class ApprovalPoint:
    """A command of a procedure (or of a sub-procedure it calls) that needs a second operator's approval."""

    procedure: Path  # the file that holds it
    number: str  # its number in that file
    command: str  # "system.command"

    def describe(self, main: Path) -> str:
        """ "2.1 cdra.vent", or "1.4 cdra.vent in lab_sub.xml" outside ``main``."""
        where = "" if self.procedure == main else f" in {self.procedure.name}"
        return f"{self.number} {self.command}{where}"


def approval_points(checked: CheckedProcedure, policy: ApprovalPolicy) -> list[ApprovalPoint]:
    """Every command of ``checked`` and its sub-procedures that needs approval under ``policy``:
    what an onboard unit must carry approved, since the habitat cannot wait a round trip for each."""
    procedures = ((Path(checked.procedure.path).resolve(), checked.procedure),) + tuple(
        (Path(path).resolve(), callee) for path, callee in checked.callees.items()
    )
    return [
        ApprovalPoint(path, instruction.number, command_name(instruction))
        for path, procedure in procedures
        for instruction in procedure.instructions
        if isinstance(instruction, CommandInstruction)
        and policy.needs_approval(True, command_hazardous(instruction, checked.sysreps))
    ]


@dataclass(frozen=True)
class CarriedApproval:
    """A second operator's approval given on the ground before an onboard unit went up, carried in
    the signed unit: the habitat sends the command on it without a round trip to the ground.

    ``procedure`` is the file's path within the unit, ``instruction`` its number there; the
    approval covers that command each time the run reaches it until ``expires_at`` (Unix seconds,
    the habitat's clock): the policy's time from when the unit is expected on the habitat. Once stale
    the command waits for a live approval from the ground.
    """

    procedure: str
    instruction: str
    command: str
    sender: str
    approver: str
    approved_at: float
    expires_at: float

    @classmethod
    def given(
        cls,
        point: ApprovalPoint,
        procedure: str,
        sender: str,
        approver: str,
        policy: ApprovalPolicy,
        *,
        in_transit: float = 0.0,
    ) -> CarriedApproval:
        """``approver``'s approval of ``point`` (``procedure``: its path within the unit), now;
        ``in_transit``: how long the unit may take to reach the habitat (the light time's
        ``uplink_within``): the approval is good for the policy's time after that, not during it."""
        if approver == sender:
            raise ValueError(f"{sender} uplinks this unit: a second operator must approve, not {sender}")
        now = policy.clock().timestamp()
        expires = now + in_transit + policy.expires_s
        return cls(procedure, point.number, point.command, sender, approver, now, expires)

    def covers(self, procedure: str, instruction: str, command: str) -> bool:
        return (self.procedure, self.instruction, self.command) == (procedure, instruction, command)

    def approval(self, request: ApprovalRequest) -> Approval:
        """The approval of ``request`` this carries, with the time it was given on the ground."""
        if request.sender != self.sender:
            raise ValueError(
                f"{request.number} was sent for approval by {request.sender}, the approval is of {self.sender}'s"
            )
        return Approval(
            request,
            self.approver,
            datetime.fromtimestamp(self.approved_at, UTC),
            datetime.fromtimestamp(self.expires_at, UTC),
        )


def missing_approvals_text(points: list[ApprovalPoint], main: Path, policy: ApprovalPolicy) -> str:
    """Why a unit without approvals may not go up: what needs them, and under which policy."""
    listed = ", ".join(point.describe(main) for point in points)
    return f"{listed} need{'s' if len(points) == 1 else ''} a second operator's approval ({policy.describe()})"


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
