"""Agents' proposals on the consoles: listed with what they cite, accepted or declined by an operator.

An assistant agent only proposes (:mod:`agent.agent_desk`); a proposal waits in the ground
database (:mod:`records.agent_proposals`) and every console lists it: the procedure and its
released version, the robot, the values the agent gives its records, its reason, and each
telemetry item it cited with the value it read then and the value now (read here, through the
robot's binding: :mod:`console.robot_telemetry`). An operator accepts it, and the run starts
under the operator's name exactly as a start from the runs list would (the same rules, refusals
and records), on the ground or on the habitat; its ``run_started`` names the proposal and the
agent. Or the operator declines it with a reason, which the agent reads back.

One acceptance starts one run: the acceptance is one conditioned UPDATE (an operator on another
console, or the agent withdrawing, loses the race cleanly), and the run's id is written into the
proposal with another. A run that did not start opens the proposal again with the reason, so
nothing the agent proposed is lost to a refused start; a habitat that has not answered yet is
not a run that did not start, and leaves the proposal accepted.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Awaitable, Callable
from functools import partial
from typing import TYPE_CHECKING, Any

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import BaseRoute, Route

from console.accounts import Account
from console.actions import ActionRefused
from console.onboard_launch import SecondOperator
from console.request_bodies import json_body, second_operator
from console.robot_telemetry import RobotTelemetry, TelemetryFacts, TelemetryRefused
from pride.accepted_proposal import AcceptedProposal
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import check_procedure
from records.agent_proposals import Proposal, ProposalStore
from records.releases import procedure_digest, short

if TYPE_CHECKING:
    from console.run_board import RunBoard

__all__ = ["ProposalDesk", "proposal_routes"]

log = logging.getLogger(__name__)

#: How many answered proposals the list shows beside the open ones.
ANSWERED_SHOWN = 10
#: s before a robot whose telemetry could not be read is tried again.
RETRY_UNREACHABLE_S = 30.0

Handler = Callable[[Request], Awaitable[Response]]
OperatorHandler = Callable[[Request, Account], Awaitable[Response]]


class ProposalDesk:
    """The proposals of ``board``'s ground database, as a console shows and answers them."""

    def __init__(self, board: RunBoard) -> None:
        self.board = board
        self.store = ProposalStore(board.audit_log.engine)
        self.telemetry = RobotTelemetry(board.catalog, board.rosbridge_urls)
        self._unreachable: dict[str, tuple[float, str]] = {}  # robot -> (when its reading failed, why)

    def close(self) -> None:
        self.telemetry.close()

    def listing(self) -> list[dict[str, Any]]:
        """Open proposals first (oldest first: the one waiting longest), then the newest answered."""
        waiting = list(reversed(self.store.proposals(open_only=True)))
        answered = [p for p in self.store.proposals(limit=len(waiting) + ANSWERED_SHOWN) if p.state != "open"]
        answered = answered[:ANSWERED_SHOWN]
        now: dict[str, dict[str, TelemetryFacts] | str] = {}
        for proposal in waiting:
            robot = proposal.proposed.robot
            if proposal.proposed.cited and robot not in now:
                now[robot] = self._read(robot)
        return [_proposal_json(p, now.get(p.proposed.robot)) for p in waiting + answered]

    def accept(
        self,
        user: str,
        proposal_id: int,
        mode: str,
        onboard: bool,
        *,
        approver: SecondOperator | None = None,
        confirm_manual: bool = False,
    ) -> str:
        """Accept proposal ``proposal_id`` as ``user`` and start its run (``onboard``: on the habitat,
        its commands that need approval approved by ``approver``, its manual instructions marked
        done there with ``confirm_manual``); the run's id.

        Raises:
            ActionRefused: 404 no such proposal; 409 it is not open, its version is not the
                procedure's current one, or it gives values for a run on the ground; whatever the
                start refuses (the proposal is open again then, with the reason).
        """
        proposal = self._open(proposal_id)
        new = proposal.proposed
        current = self._current_version(new.procedure_file)
        if current != new.sha256:
            raise ActionRefused(
                409,
                f"proposal {proposal_id} is of {new.procedure_file} sha256 {short(new.sha256)}; the file is "
                f"{short(current)} now: decline it, and the agent may propose the current version",
            )
        if new.inputs and not onboard:
            raise ActionRefused(
                409,
                f"proposal {proposal_id} gives values for {', '.join(sorted(new.inputs))}: they go up with a run on "
                "the habitat; a run here asks its operator for them (decline it, or run it on the habitat)",
            )
        if not self.store.close(proposal_id, "accepted", user):
            raise ActionRefused(409, f"proposal {proposal_id} is {self._state(proposal_id)}: it cannot be accepted")
        try:
            if onboard:  # the onboard start takes the proposal itself (records/proposal_runs.py)
                start = partial(
                    self.board.start_onboard, approver=approver, proposal=proposal_id, confirm_manual=confirm_manual
                )
                run_id = start(user, new.procedure_file, new.binding, mode)
            else:
                accepted = AcceptedProposal(proposal_id, new.agent, new.reason)
                run_id = self.board.start(user, new.procedure_file, new.binding, mode, proposal=accepted).run_id
                self.store.started(proposal_id, user, run_id)
        except Exception as exc:
            refused = exc if isinstance(exc, ActionRefused) else None
            if refused is None or refused.details.get("ended", True):  # nothing runs: the proposal waits again
                self.store.reopen(proposal_id, user, refused.message if refused else f"the start failed: {exc}")
            raise
        log.info("%s accepted proposal %d of agent %s: run %s", user, proposal_id, new.agent, run_id)
        return run_id

    def decline(self, user: str, proposal_id: int, reason: str) -> None:
        """Decline proposal ``proposal_id`` as ``user`` for ``reason`` (the agent reads it back)."""
        if not reason.strip():
            raise ActionRefused(400, "a proposal is declined with a reason, for the agent that made it")
        self._open(proposal_id)
        if not self.store.close(proposal_id, "declined", user, reason.strip()):
            raise ActionRefused(409, f"proposal {proposal_id} is {self._state(proposal_id)}: it cannot be declined")
        log.info("%s declined proposal %d: %s", user, proposal_id, reason.strip())

    def _open(self, proposal_id: int) -> Proposal:
        proposal = self.store.get(proposal_id)
        if proposal is None:
            raise ActionRefused(404, f"no proposal {proposal_id}")
        if proposal.state != "open":
            raise ActionRefused(409, f"proposal {proposal_id} is {proposal.state}: nothing to answer")
        return proposal

    def _state(self, proposal_id: int) -> str:
        proposal = self.store.get(proposal_id)
        return proposal.state if proposal is not None else "gone"

    def _current_version(self, procedure_file: str) -> str:
        try:
            path = self.board.catalog.procedure_path(procedure_file)
            return procedure_digest(check_procedure(path, self.board.sysreps()))
        except ProcedureError as exc:
            raise ActionRefused(409, f"{procedure_file} has problems now and cannot run:\n{exc}") from None

    def _read(self, robot: str) -> dict[str, TelemetryFacts] | str:
        """``robot``'s telemetry now by ``system.item``, or why it cannot be read (shown as such; a
        robot that could not be reached is not tried again for :data:`RETRY_UNREACHABLE_S`, so a
        list every browser reads every few seconds does not open a PAX host each time)."""
        failed = self._unreachable.get(robot)
        if failed is not None and time.monotonic() - failed[0] < RETRY_UNREACHABLE_S:
            return failed[1]
        try:
            return {f"{fact.system}.{fact.item.id}": fact for fact in self.telemetry.read(robot)}
        except TelemetryRefused as exc:
            return exc.message
        except Exception as exc:  # the robot's PAX host or rosbridge: the card says so, the list still shows
            log.warning("cannot read %s's telemetry for its proposals", robot, exc_info=True)
            self._unreachable[robot] = (time.monotonic(), f"{robot}'s telemetry cannot be read: {exc}")
            return self._unreachable[robot][1]


def _proposal_json(proposal: Proposal, now: dict[str, TelemetryFacts] | str | None) -> dict[str, Any]:
    new = proposal.proposed
    cited = []
    for item in new.cited:
        fact = now.get(f"{item.system}.{item.item}") if isinstance(now, dict) else None
        cited.append(
            {
                "system": item.system,
                "item": item.item,
                "then": {"value": item.value, "state": item.state},
                "now": None if fact is None else {"value": fact.value, "state": fact.state},
                "units": fact.item.units if fact is not None else None,
            }
        )
    return {
        "id": proposal.id,
        "agent": new.agent,
        "procedure": new.procedure,
        "procedure_file": new.procedure_file,
        "release": new.release,
        "sha256": new.sha256,
        "robot": new.robot,
        "binding": new.binding,
        "inputs": new.inputs,
        "reason": new.reason,
        "cited": cited,
        "telemetry_error": now if isinstance(now, str) else None,
        "created": proposal.created.isoformat(),
        "expires": proposal.expires.isoformat(),
        "state": proposal.state,
        "closed_by": proposal.closed_by,
        "answer": proposal.answer,
        "run_id": proposal.run_id,
    }


def proposal_routes(
    board: RunBoard,
    *,
    api: Callable[[Handler], Handler],
    account: Callable[[Request], Account],
    operators: Callable[[str], Callable[[OperatorHandler], Handler]],
) -> tuple[ProposalDesk, list[BaseRoute]]:
    """The desk and its routes, given the app's refusal handling (``api``), session (``account``)
    and role check (``operators``): ``GET /api/proposals``, ``POST /api/proposals/ID/accept``
    (``{"mode": "manual"|"autonomous", "onboard": bool}``, and for an onboard run whose commands
    need approval ``approver`` and ``approver_password``, as a start from the form, and
    ``confirm_manual``: the habitat marks its manual instructions done) and ``POST
    /api/proposals/ID/decline`` (``{"reason": text}``)."""
    desk = ProposalDesk(board)

    @api
    async def listing(request: Request) -> Response:
        account(request)
        return JSONResponse({"proposals": await run_in_threadpool(desk.listing)})

    @api
    @operators("watch, not answer proposals")
    async def accept(request: Request, operator: Account) -> Response:
        asked = await json_body(request)
        if not isinstance(asked, dict) or asked.get("mode") not in ("manual", "autonomous"):
            raise ActionRefused(400, 'expected {"mode": "manual" or "autonomous", "onboard": true or false}')
        onboard = asked.get("onboard") is True
        approver = await second_operator(request, operator.user) if onboard else None
        accept_it = partial(
            desk.accept, approver=approver, confirm_manual=onboard and asked.get("confirm_manual") is True
        )
        run_id = await run_in_threadpool(
            accept_it, operator.user, request.path_params["proposal_id"], asked["mode"], onboard
        )
        board.list_watchers.wake()
        return JSONResponse({"run_id": run_id}, status_code=201)

    @api
    @operators("watch, not answer proposals")
    async def decline(request: Request, operator: Account) -> Response:
        asked = await json_body(request)
        if not isinstance(asked, dict) or not isinstance(asked.get("reason"), str):
            raise ActionRefused(400, 'expected {"reason": why you decline it, for the agent}')
        await run_in_threadpool(desk.decline, operator.user, request.path_params["proposal_id"], asked["reason"])
        return JSONResponse({"declined": request.path_params["proposal_id"]})

    return desk, [
        Route("/api/proposals", listing),
        Route("/api/proposals/{proposal_id:int}/accept", accept, methods=["POST"]),
        Route("/api/proposals/{proposal_id:int}/decline", decline, methods=["POST"]),
    ]
