"""Attach, on the runs list: a new supervising runner for an onboard run whose supervisor is gone.

An onboard run's supervising runner (``caretaker run --onboard``) hosts it for the consoles. When
the runner stops (``RESULT detached``) or dies, the run goes on on the habitat, and its host row
stays with its lease run out (:meth:`RunHosting.lapse`), its last published view saying it is an
onboard run. The runs list offers such a run to operators (:meth:`RunHosting.unsupervised`; the page shows
the offer to operators only, the route refuses observers as a start does); Attach starts
``caretaker run --attach RUN`` on this console's host with the binding and rosbridge URL this
console uses for onboard starts (:func:`console.onboard_launch.attach_onboard`), which catches the
ground's record up and hosts the run again. A run whose supervisor holds it is refused, naming
that supervisor, and the refusal recorded (:mod:`console.attach_records`); the runner records the
attach, and its own refusal when another attached first.
"""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import BaseRoute, Route

from console.accounts import Account
from console.actions import ActionRefused
from console.attach_records import record_attach_refused
from console.onboard_launch import LaunchRefused, attach_onboard
from pride.states import RefusalRule

if TYPE_CHECKING:  # the board lists runs with this module's offer
    from console.run_board import RunBoard

__all__ = ["attach", "attach_routes"]

log = logging.getLogger(__name__)

#: A route's handler, and one only operators may call (given the signed-in operator).
Handler = Callable[[Request], Awaitable[Response]]
OperatorHandler = Callable[[Request, Account], Awaitable[Response]]


def attach(board: RunBoard, user: str, run_id: str) -> None:
    """Start a supervising runner for ``run_id`` as ``user`` and wait until it follows the run.

    Raises:
        ActionRefused: 404 for a run that is no onboard run hosted on this ground; 409 while a
            supervisor holds it (``held_by`` names it; recorded); 400 for a binding this console
            does not offer; 502 with the runner's words when it did not attach.
    """
    record = board.hosting.record(run_id)
    if record is None or not board.hosting.onboard(run_id):
        raise ActionRefused(404, f"run {run_id!r} is no onboard run hosted on this ground: nothing to attach to")
    if record.alive:
        refused = ActionRefused(
            409,
            f"run {run_id} has a supervisor: {record.host} holds it (since {record.claimed:%H:%M:%S} UTC)",
            {"held_by": {"host": record.host, "since": record.claimed.isoformat()}},
            rule=RefusalRule.ONE_SUPERVISOR,
        )
        record_attach_refused(board.audit_log, user, run_id, RefusalRule.ONE_SUPERVISOR, refused.message)
        raise refused
    binding = board.catalog.binding_path(record.binding)
    try:
        attach_onboard(
            run_id,
            binding,
            user=user,
            db_url=board.audit_log.url,
            sysreps=board.catalog.sysreps,
            rosbridge=board.rosbridge_url_for(record.binding),
        )
    except LaunchRefused as exc:
        raise ActionRefused(502, f"run {run_id} was not attached:\n{exc}") from None
    log.info("%s attached a supervising runner to onboard run %s", user, run_id)
    board.list_watchers.wake()


def attach_routes(
    *, api: Callable[[Handler], Handler], operators: Callable[[str], Callable[[OperatorHandler], Handler]]
) -> list[BaseRoute]:
    """``POST /api/runs/RUN/attach``, given the app's refusal handling (``api``) and its one role
    check (``operators``), so the request is checked exactly as a start is."""

    @api
    @operators("watch, not attach supervisors to runs")
    async def attach_route(request: Request, account: Account) -> Response:
        run_id = request.path_params["run_id"]
        await run_in_threadpool(attach, request.app.state.board, account.user, run_id)
        return JSONResponse({"run_id": run_id}, status_code=201)

    return [Route("/api/runs/{run_id}/attach", attach_route, methods=["POST"])]
