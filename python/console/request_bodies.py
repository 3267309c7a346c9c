"""What a request to the console carries in its body: JSON, and a second operator's approval.

Shared by the console's routes (:mod:`console.app`) and those that answer agents' proposals
(:mod:`console.proposals`), so a body is read, and a second operator checked, one way.
"""

from __future__ import annotations

import json
import logging
from typing import Any

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request

from console.actions import ActionRefused
from console.onboard_launch import SecondOperator
from console.sign_in import SignInRefused, SignIns

__all__ = ["json_body", "second_operator"]

log = logging.getLogger(__name__)


async def json_body(request: Request) -> Any:
    """The body as JSON; ActionRefused 400 when it is not."""
    try:
        return await request.json()
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise ActionRefused(400, "the request body must be JSON") from None


async def second_operator(request: Request, for_user: str) -> SecondOperator | None:
    """The second operator approving, at ``for_user``'s console, the commands of an onboard unit
    (the body's ``approver`` and ``approver_password``), signed in here for that alone; None if
    the body names none. A wrong password is refused as at sign-in (throttled), but as 403: the
    operator at the console stays signed in."""
    body = await json_body(request)
    user, password = body.get("approver"), body.get("approver_password")
    if not user:
        return None
    if not isinstance(user, str) or not isinstance(password, str):
        raise ActionRefused(400, "approver and approver_password must be strings")
    address = request.client.host if request.client else "unknown"
    sign_ins: SignIns = request.app.state.sign_ins
    try:
        account = await run_in_threadpool(sign_ins.second_operator, user.strip(), password, address, for_user)
    except SignInRefused as exc:
        log.warning("approval by %r at %s's console refused: %s", user[:64], for_user, exc.message)
        raise ActionRefused(429 if exc.status == 429 else 403, f"the second operator: {exc.message}") from None
    log.info("%s approves, at %s's console, the commands of an onboard unit", account.user, for_user)
    return SecondOperator(account.user, password)
