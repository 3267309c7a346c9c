"""Operator actions from the page, sent to the executive under the signed-in user's id.

This is the only place the web view changes a run, whether the action comes from this console's
page or is forwarded from another console to the run's host (:func:`perform_forwarded`). Each
action is one executive method; the executive records it in the audit log with the user id and
refuses what does not apply now (:class:`~pride.executive.OperatorActionError`). The role check
happens here, on the server, before anything reaches the executive: an observer's request is
refused whatever the page shows.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from console.accounts import Account, AccountStore, Role
from ground.action_requests import Answer, ForwardedAction, OnItsWay
from pride import event_payloads as ep
from pride.executive import Executive, Mode, OperatorActionError
from pride.states import RefusalRule

__all__ = [
    "ACTIONS",
    "ONBOARD_ACTIONS",
    "ActionRefused",
    "ActionRequest",
    "OnboardSend",
    "mode_named",
    "perform_action",
    "perform_forwarded",
    "perform_onboard",
    "record_refused",
]


class ActionRefused(Exception):
    """The request cannot be carried out; ``status`` is the HTTP status that says why, ``details``
    what the page needs to offer a way on (e.g. who controls the robot, to take it over).

    ``rule``: the rule that refused an operator's act, which is then on the record
    (``action_refused``); None for a request that is no act (malformed, unknown, a failure to
    reach something)."""

    def __init__(
        self, status: int, message: str, details: dict[str, Any] | None = None, *, rule: RefusalRule | None = None
    ) -> None:
        super().__init__(message)
        self.status = status
        self.message = message
        self.details = details or {}
        self.rule = rule


@dataclass(frozen=True)
class ActionRequest:
    """What the page asks: an action name, the instruction it was clicked on, and its values."""

    action: str
    instruction: str | None = None
    value: Any = None
    reason: str = ""
    mode: str | None = None

    @staticmethod
    def from_json(body: Any) -> ActionRequest:
        if not isinstance(body, dict) or not isinstance(body.get("action"), str):
            raise ActionRefused(400, "expected a JSON object with an 'action' string")
        mode = body.get("mode")
        instruction = body.get("instruction")
        return ActionRequest(
            action=body["action"],
            instruction=str(instruction) if instruction is not None else None,
            value=body.get("value"),
            reason=str(body.get("reason") or ""),
            mode=str(mode) if mode is not None else None,
        )

    def to_json(self) -> dict[str, Any]:
        """The request as :meth:`from_json` reads it (to forward it to the run's host)."""
        return {name: value for name, value in self.__dict__.items() if value is not None}


def mode_named(name: str | None) -> Mode:
    """The run mode ``name`` names; ActionRefused 400 naming the modes there are."""
    try:
        return Mode(name)
    except ValueError:
        raise ActionRefused(400, f"mode must be one of {', '.join(m.value for m in Mode)} (got {name!r})") from None


def _numbered(request: ActionRequest) -> str:
    if not request.instruction:
        raise ActionRefused(400, f"{request.action} needs the instruction number")
    return request.instruction


def _outcome(request: ActionRequest) -> str:
    if request.value not in ("succeeded", "failed"):
        raise ActionRefused(
            400, f"resolve needs value 'succeeded' or 'failed': what the system shows (got {request.value!r})"
        )
    return str(request.value)


#: action name -> (needs the clicked instruction to be the current one, what it does)
ACTIONS: dict[str, tuple[bool, Callable[[Executive, str, ActionRequest], Any]]] = {
    "perform": (True, lambda ex, user, r: ex.perform(user)),
    "step": (False, lambda ex, user, r: ex.step(user)),
    "confirm": (True, lambda ex, user, r: ex.confirm(user)),
    "approve": (True, lambda ex, user, r: ex.approve(user)),
    "enter": (True, lambda ex, user, r: ex.enter(user, r.value)),
    "done": (True, lambda ex, user, r: ex.mark_done(user)),
    "retry": (True, lambda ex, user, r: ex.retry(user)),
    "skip": (True, lambda ex, user, r: ex.skip(user, r.reason)),
    "mode": (False, lambda ex, user, r: ex.set_mode(user, mode_named(r.mode))),
    "pause": (False, lambda ex, user, r: ex.pause(user)),
    "continue": (False, lambda ex, user, r: ex.resume_automation(user)),
    # An operator's stop keeps the run's templates, listed in its end, so the next shift can
    # resume it; an unattended stop (``caretaker run``) takes them back.
    "stop": (False, lambda ex, user, r: ex.stop(user, r.reason, take_back=False)),
    "halt": (False, lambda ex, user, r: ex.halt(user, r.reason)),
    "take_control": (False, lambda ex, user, r: ex.take_control(user, r.reason)),
    "ask_again": (True, lambda ex, user, r: ex.ask_again(user)),
    "resolve": (True, lambda ex, user, r: ex.resolve(user, _outcome(r), r.reason)),
    "correct_record": (False, lambda ex, user, r: ex.correct_record(user, _numbered(r), r.value, r.reason)),
    "go_back": (False, lambda ex, user, r: ex.go_back(user, _numbered(r), r.reason)),
    "replan": (True, lambda ex, user, r: ex.replan(user)),
    "set_breakpoint": (False, lambda ex, user, r: ex.set_breakpoint(user, _numbered(r))),
    "clear_breakpoint": (False, lambda ex, user, r: ex.clear_breakpoint(user, _numbered(r))),
}


def _require_operator(account: Account, action: str = "") -> None:
    """Only an operator acts on a run; an agent may ask for its HALT (the safe direction), no more."""
    if action == "halt" and account.may_halt:
        return
    if not account.may_act:
        why = "an agent asks for a halt, never acts" if account.role is Role.AGENT else "observers may watch, not act"
        raise ActionRefused(
            403,
            f"{account.user} is an {account.role.value}: {why}",
            rule=RefusalRule.OBSERVERS_WATCH,
        )


def perform_action(executive: Executive, account: Account, request: ActionRequest) -> Any:
    """Carry out ``request`` as ``account``; ActionRefused says why not, and a refused act is
    recorded in the run's log with the rule that refused it (once: the executive records some itself)."""
    try:
        return _perform(executive, account, request)
    except ActionRefused as exc:
        asked = {k: v for k, v in request.to_json().items() if k != "action" and v != ""}
        record_refused(executive, account.user, request.action, exc, request.instruction, asked)
        raise


def record_refused(
    executive: Executive,
    user: str,
    action: str,
    refused: ActionRefused,
    instruction: str | None = None,
    asked: Mapping[str, Any] | None = None,
) -> None:
    """Put a refused act in the run's log with the rule that refused it (a refusal without a rule,
    of a malformed request, is no act and is not recorded)."""
    if refused.rule is not None:
        data = ep.ActionRefused(action=action, rule=refused.rule.value, reason=refused.message, asked=asked or None)
        executive.record_refusal(user, instruction, data)


def _perform(executive: Executive, account: Account, request: ActionRequest) -> Any:
    """Actions clicked on an instruction name it, and are refused unless it is still the current
    one: two operators looking at the same run must not act on an instruction that moved on."""
    _require_operator(account, request.action)
    entry = ACTIONS.get(request.action)
    if entry is None:
        raise ActionRefused(400, f"unknown action {request.action!r} (known: {', '.join(ACTIONS)})")
    on_current, action = entry
    if on_current:
        current = executive.snapshot().current
        if request.instruction is None:
            raise ActionRefused(400, f"{request.action} needs the instruction number it was clicked on")
        if request.instruction != current:
            raise ActionRefused(
                409,
                f"{request.instruction} is not the current instruction (the run is at {current or 'no instruction'})",
                rule=RefusalRule.CURRENT_INSTRUCTION,
            )
    try:
        return action(executive, account.user, request)
    except OperatorActionError as exc:
        raise ActionRefused(409, str(exc), rule=None if exc.recorded else exc.rule) from None


def perform_forwarded(
    executive: Executive | None, accounts: AccountStore, request: ForwardedAction, host: str
) -> Answer:
    """An action another console forwarded to the run's host (``host``, this process): performed as its
    operator, whose account and role are checked here against the database, whatever the other console did."""
    if executive is None:
        return Answer(404, {"error": f"run {request.run_id} is no longer live on {host}"})
    try:
        account = _forwarded_account(accounts, request)
        action = ActionRequest.from_json(request.action)
        result = perform_action(executive, account, action)
    except ActionRefused as exc:
        return Answer(exc.status, {"error": exc.message})
    return Answer(200, {"ok": True, "action": action.action, "result": result})


def _forwarded_account(accounts: AccountStore, request: ForwardedAction) -> Account:
    """The forwarded request's operator, as this host's database has them (whatever the asking console did)."""
    account = accounts.get(request.user)
    if account is None:
        raise ActionRefused(403, f"{request.user!r} has no account (any more)")
    return account


#: Sends an operator's action on an onboard run up the link: (action, user, args, on its way) →
#: (state, message), state DONE | REFUSED | EXPIRED, or UNKNOWN when the habitat did not answer in
#: time; it tells "on its way" when the action went up, and when its answer is due, before that answer.
OnboardSend = Callable[[str, str, Mapping[str, Any], OnItsWay], tuple[str, str]]

#: Actions the habitat takes on an onboard run, and the arguments each sends up. Those clicked on
#: an instruction name it: the habitat refuses them if its run has moved on meanwhile (the page
#: saw the run one light time ago). The rest of :data:`ACTIONS` changes how the ground runs a
#: procedure (mode, breakpoints, going back, corrections) and is not offered for onboard runs.
ONBOARD_ACTIONS: dict[str, Callable[[str, ActionRequest], dict[str, Any]]] = {
    "halt": lambda user, r: {"reason": r.reason or f"halted from the console by {user}"},
    "pause": lambda user, r: {},
    "continue": lambda user, r: {},
    "stop": lambda user, r: {"reason": r.reason or f"stopped from the console by {user}"},
    "perform": lambda user, r: {"instruction": _numbered(r)},
    "confirm": lambda user, r: {"instruction": _numbered(r)},
    # a carried approval that ran out before the run reached its command: approved live
    "approve": lambda user, r: {"instruction": _numbered(r)},
    "enter": lambda user, r: {"instruction": _numbered(r), "value": r.value},
    "done": lambda user, r: {"instruction": _numbered(r)},
    "retry": lambda user, r: {"instruction": _numbered(r)},
    "replan": lambda user, r: {"instruction": _numbered(r)},
    "skip": lambda user, r: {"instruction": _numbered(r), "reason": r.reason},
    "ask_again": lambda user, r: {"instruction": _numbered(r)},
    "resolve": lambda user, r: {"instruction": _numbered(r), "value": _outcome(r), "reason": r.reason},
}


def perform_onboard(send: OnboardSend, accounts: AccountStore, request: ForwardedAction) -> Answer:
    """An action on an onboard run, forwarded to the runner that supervises it: the role is checked
    here, then it goes up to the habitat, which acts on it (or refuses) and says so; meanwhile the
    console hears that it went up and when its answer is due (:meth:`ForwardedAction.on_its_way`)."""
    try:
        account = _forwarded_account(accounts, request)
        action = ActionRequest.from_json(request.action)
        _require_operator(account, action.action)
        arguments = ONBOARD_ACTIONS.get(action.action)
        if arguments is None:
            raise ActionRefused(
                409,
                f"{action.action} is not taken by an onboard run (the habitat takes: {', '.join(ONBOARD_ACTIONS)})",
            )
        args = arguments(account.user, action)
    except ActionRefused as exc:
        return Answer(exc.status, {"error": exc.message})
    state, message = send(action.action, account.user, args, request.on_its_way)
    if state == "DONE":
        return Answer(200, {"ok": True, "action": action.action, "result": f"on the habitat: {message}"})
    if state == "UNKNOWN":
        return Answer(504, {"error": f"outcome unknown: {message}"})
    return Answer(409, {"error": f"the habitat {state.lower()} it: {message}"})
