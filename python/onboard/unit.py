"""What the ground sends up: a procedure unit to run onboard, and an operator's action on that run.

Both travel as canonical JSON (sorted keys, no spaces, UTF-8) with a hex HMAC-SHA256 signature
under the link's shared secret (the bridge's ``auth_secret_file``: whoever may log in to the
habitat's bridge may also sign). A unit is identified by the SHA-256 of its JSON: the habitat
acknowledges that hash, so the ground knows exactly what the habitat took. Both carry an expiry
(Unix seconds): a unit or action that arrives after it is refused as expired, never acted on late.

Everything read here comes from the link and is checked field by field; a bad one raises
:class:`UnitError` naming the field and what was expected.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import re
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import PurePosixPath
from typing import Any

from pride.accepted_proposal import AcceptedProposal
from pride.approvals import CarriedApproval
from pride.run_version import RunVersion

__all__ = [
    "ACTIONS",
    "ACTION_SERVICE",
    "EVENTS_SERVICE",
    "FOLLOW_SERVICE",
    "STATUS_SERVICE",
    "UNIT_SERVICE",
    "UPLINK_SERVICE",
    "OperatorAction",
    "Unit",
    "UnitError",
    "canonical",
    "digest",
    "sign",
    "signed_by",
]

#: The onboard executive's services on the habitat's bridge (caretaker_onboard_msgs).
UPLINK_SERVICE = "/caretaker_onboard/uplink"
EVENTS_SERVICE = "/caretaker_onboard/events"
#: RunEvents for a ground that keeps several requests waiting: each event goes down once (onboard.followers).
FOLLOW_SERVICE = "/caretaker_onboard/follow"
ACTION_SERVICE = "/caretaker_onboard/action"
STATUS_SERVICE = "/caretaker_onboard/status"
UNIT_SERVICE = "/caretaker_onboard/unit"

#: Operators' actions the habitat takes for an onboard run, named as the console names them, with
#: the arguments each needs. Any may name the ``instruction`` it was clicked on: the habitat then
#: refuses it if the run has moved on meanwhile.
ACTIONS: Mapping[str, tuple[str, ...]] = {
    "halt": ("reason",),
    "pause": (),
    "continue": (),
    "stop": ("reason",),
    "perform": (),
    "skip": ("reason",),
    "enter": ("value",),
    "done": (),
    "confirm": (),
    "approve": (),
    "retry": (),
    "replan": (),
    "ask_again": (),
    "resolve": ("value", "reason"),
}
_RUN_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._:-]{0,127}")


class UnitError(ValueError):
    """A unit or action that cannot be taken as sent: the text names the field and what to fix."""


def canonical(value: Mapping[str, Any]) -> str:
    """The one JSON text of ``value`` that is hashed and signed."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def digest(text: str) -> str:
    """SHA-256 of ``text`` (UTF-8), hex: a unit's identity."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def sign(text: str, secret: str) -> str:
    """The hex HMAC-SHA256 of ``text`` under ``secret``."""
    return hmac.new(secret.encode("utf-8"), text.encode("utf-8"), hashlib.sha256).hexdigest()


def signed_by(text: str, signature: str, secret: str) -> bool:
    """Whether ``signature`` is ``text``'s under ``secret`` (in constant time)."""
    return hmac.compare_digest(sign(text, secret), signature)


@dataclass(frozen=True)
class Unit:
    """One procedure to run onboard, with everything the run may answer by itself.

    ``files`` holds the procedure and every sub-procedure it calls, by path relative to one
    folder (``procedure`` names the one to run); ``binding`` names one of the habitat's own
    binding files; ``values``, ``confirm_manual`` and ``confirm_hazardous`` are the answers the
    operator gave at uplink (as ``caretaker run --set``, ``--confirm-manual``,
    ``--confirm-hazardous``): any other hold waits for the ground. ``approvals`` are the second
    operator's approvals of the commands that need one (:class:`pride.approvals.CarriedApproval`),
    given on the ground before the unit went up and signed with it. ``version`` is the procedure
    version the ground let it run (:class:`pride.run_version.RunVersion`: its release, or a
    rehearsal), recorded in its ``run_started``. ``section``: a run of part of the procedure
    (``{"from": STEP, "to": STEP or null}``, :class:`pride.run_section.RunSection`), ``values``
    then also giving what the steps it skips would have bound; absent: the whole procedure.
    ``proposal``: the agent's proposal an operator accepted to start the run, recorded in its
    ``run_started`` (:class:`pride.accepted_proposal.AcceptedProposal`); absent: none.
    """

    run_id: str
    procedure: str
    files: Mapping[str, str]
    binding: str
    user: str
    mode: str
    issued_at: float
    expires_at: float
    values: Mapping[str, str] = field(default_factory=dict)
    confirm_manual: bool = False
    confirm_hazardous: bool = False
    breakpoints: tuple[str, ...] = ()
    version: RunVersion | None = None
    approvals: tuple[CarriedApproval, ...] = ()
    section: Mapping[str, str | None] | None = None
    proposal: AcceptedProposal | None = None

    def to_json(self) -> str:
        data = {**asdict(self), "files": dict(self.files), "values": dict(self.values)}
        if self.section is None:
            del data["section"]  # a whole-procedure unit reads (and hashes) as before sections
        else:
            data["section"] = dict(self.section)
        if self.proposal is None:
            del data["proposal"]  # as sections: a unit without one reads (and hashes) as before
        return canonical(data)

    def approval_of(self, procedure: str, instruction: str, command: str) -> CarriedApproval | None:
        """The carried approval of that command (``procedure``: its file within the unit), if any."""
        return next((a for a in self.approvals if a.covers(procedure, instruction, command)), None)

    @classmethod
    def from_json(cls, text: str) -> Unit:
        data = _object(text, "unit")
        files = _field(data, "files", dict, "an object of file path → procedure XML text")
        for name, content in files.items():
            _relative_path(name)
            if not isinstance(content, str):
                raise UnitError(f"files[{name!r}] must be the file's text, not {type(content).__name__}")
        procedure = _field(data, "procedure", str, "the path of the procedure to run, one of files")
        if procedure not in files:
            raise UnitError(f"procedure {procedure!r} is not one of the unit's files ({', '.join(sorted(files))})")
        values = _field(data, "values", dict, "an object of record name → value text")
        if not all(isinstance(v, str) for v in values.values()):
            raise UnitError("values must map each record name to its value as text")
        breakpoints = _field(data, "breakpoints", list, "a list of instruction numbers")
        if not all(isinstance(b, str) for b in breakpoints):
            raise UnitError('breakpoints must be instruction numbers as text, e.g. "2.3"')
        mode = _field(data, "mode", str, '"autonomous" or "manual"')
        if mode not in ("autonomous", "manual"):
            raise UnitError(f'mode must be "autonomous" or "manual", not {mode[:40]!r}')
        return cls(
            run_id=_run_id(data),
            procedure=procedure,
            files=files,
            binding=_relative_path(_field(data, "binding", str, "the file name of one of the habitat's bindings")),
            user=_field(data, "user", str, "who uplinked it"),
            mode=mode,
            issued_at=_time(data, "issued_at"),
            expires_at=_time(data, "expires_at"),
            values=values,
            confirm_manual=_field(data, "confirm_manual", bool, "true or false"),
            confirm_hazardous=_field(data, "confirm_hazardous", bool, "true or false"),
            breakpoints=tuple(breakpoints),
            version=_version(data.get("version")),
            approvals=tuple(
                _approval(a, i, files)
                for i, a in enumerate(
                    _field(data, "approvals", list, "a list of approvals") if "approvals" in data else []
                )
            ),
            section=_section(data.get("section")),
            proposal=_proposal(data.get("proposal")),
        )


@dataclass(frozen=True)
class OperatorAction:
    """An operator's action on an onboard run: ``key`` is unique per action (a resend under the
    same key is answered with the first outcome, never acted on twice)."""

    key: str
    run_id: str
    action: str
    user: str
    expires_at: float
    args: Mapping[str, Any] = field(default_factory=dict)

    def to_json(self) -> str:
        return canonical({**asdict(self), "args": dict(self.args)})

    @classmethod
    def from_json(cls, text: str) -> OperatorAction:
        data = _object(text, "action")
        action = _field(data, "action", str, f"one of {', '.join(ACTIONS)}")
        if action not in ACTIONS:
            raise UnitError(f"action {action[:40]!r} is not one the habitat takes ({', '.join(ACTIONS)})")
        args = _field(data, "args", dict, "an object of the action's arguments")
        missing = [name for name in ACTIONS[action] if name not in args]
        if missing:
            raise UnitError(f"action {action} needs {', '.join(missing)} in args")
        if not isinstance(args.get("instruction", ""), str):
            raise UnitError('args.instruction must be an instruction number as text, e.g. "2.7"')
        key = _field(data, "key", str, "a key unique to this action")
        if not 0 < len(key) <= 200:
            raise UnitError("key must be 1 to 200 characters")
        return cls(key, _run_id(data), action, _field(data, "user", str, "who acts"), _time(data, "expires_at"), args)


def _object(text: str, what: str) -> dict[str, Any]:
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise UnitError(f"the {what} is not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise UnitError(f"the {what} must be a JSON object, not {type(data).__name__}")
    return data


def _section(data: Any) -> dict[str, str | None] | None:
    """The unit's ``section`` (absent: the whole procedure): the step it starts at, the step it ends after."""
    if data is None:
        return None
    if not isinstance(data, dict) or set(data) - {"from", "to"}:
        raise UnitError('section must be an object of "from" (a step) and "to" (a step or null)')
    start, stop = data.get("from"), data.get("to")
    if not isinstance(start, str) or not (stop is None or isinstance(stop, str)):
        raise UnitError("section.from must name a step, and section.to a step or null")
    return {"from": start, "to": stop}


def _proposal(data: Any) -> AcceptedProposal | None:
    """The unit's ``proposal`` (absent: the run answers none)."""
    if data is None:
        return None
    try:
        return AcceptedProposal.from_json(data)
    except ValueError as exc:
        raise UnitError(str(exc)) from None


def _version(data: Any) -> RunVersion | None:
    """The unit's ``version`` (absent: a unit from before versions were recorded)."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise UnitError(f"version must be an object of sha256, release and rehearsal, not {type(data).__name__}")
    release = data.get("release")
    if release is not None and (isinstance(release, bool) or not isinstance(release, int)):
        raise UnitError(f"version.release must be a release number or null, not {str(release)[:40]!r}")
    return RunVersion(
        _field(data, "sha256", str, "the procedure version's sha256"),
        release,
        _field(data, "rehearsal", bool, "true or false"),
    )


def _approvals(data: Mapping[str, Any]) -> list[Any]:
    """The unit's ``approvals`` (absent: a unit from before approvals were carried)."""
    return _field(data, "approvals", list, "a list of approvals") if "approvals" in data else []


def _approval(data: Any, index: int, files: Mapping[str, str]) -> CarriedApproval:
    """``approvals[index]``: a second operator's approval of one command of the unit's files."""
    where = f"approvals[{index}]"
    if not isinstance(data, dict):
        raise UnitError(f"{where} must be an object of procedure, instruction, command, sender, approver and times")
    try:
        procedure = _field(data, "procedure", str, "the path of one of the unit's files")
        if procedure not in files:
            raise UnitError(f"procedure {procedure[:80]!r} is not one of the unit's files")
        approval = CarriedApproval(
            procedure=procedure,
            instruction=_field(data, "instruction", str, 'an instruction number as text, e.g. "2.3"'),
            command=_field(data, "command", str, '"system.command"'),
            sender=_field(data, "sender", str, "who sends the command"),
            approver=_field(data, "approver", str, "the second operator who approved it"),
            approved_at=_time(data, "approved_at"),
            expires_at=_time(data, "expires_at"),
        )
    except UnitError as exc:
        raise UnitError(f"{where}.{exc}") from None
    if approval.approver == approval.sender:
        raise UnitError(f"{where}: {approval.sender} may not approve their own command")
    return approval


def _field(data: Mapping[str, Any], name: str, kind: type, expected: str) -> Any:
    if name not in data:
        raise UnitError(f"{name} is missing: expected {expected}")
    value = data[name]
    if not isinstance(value, kind) or (kind in (int, float) and isinstance(value, bool)):
        raise UnitError(f"{name} must be {expected}, not {type(value).__name__}")
    return value


def _time(data: Mapping[str, Any], name: str) -> float:
    value = data.get(name)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1e11:
        raise UnitError(f"{name} must be a time in Unix seconds, not {str(value)[:40]!r}")
    return float(value)


def _run_id(data: Mapping[str, Any]) -> str:
    run_id = _field(data, "run_id", str, "the run's id")
    if not _RUN_ID.fullmatch(run_id):
        raise UnitError(f"run_id {run_id[:40]!r} must be letters, digits and . _ : - (at most 128)")
    return str(run_id)


def _relative_path(name: str) -> str:
    """A file name that stays inside the unit's folder on the habitat."""
    path = PurePosixPath(name)
    if not name or path.is_absolute() or ".." in path.parts or "\\" in name or "\0" in name or len(name) > 255:
        raise UnitError(f"file path {name[:80]!r} must be relative, without '..', at most 255 characters")
    return name
