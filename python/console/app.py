"""The web view's routes: the page, its JSON API, the live WebSocket, camera images, reports.

Reading is open to every signed-in person; changing anything (starting or resuming a run, any
operator action, saving a procedure) needs the operator role and goes through :mod:`console.actions`
to the executive — of this console, or, for a run another console hosts, of that console, through the
database (:meth:`RunBoard.act`). Two WebSockets push news: one run's state, events and telemetry
(``/ws/runs/ID``), and the runs list (``/ws/runs``). Every request that changes state carries the
session's CSRF token (header ``X-CSRF-Token``) and, when a browser sends one, an ``Origin`` of this
server; the WebSocket only reports (actions go over HTTP) and checks the session and the Origin when
it opens. Blocking work (password hashing, executive calls that take its lock, gateway reads, opening
a gateway, the audit log) runs in the thread pool so one slow robot never stalls the other browsers.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from functools import partial
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection, Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from console.accounts import Account
from console.actions import ActionRefused, ActionRequest
from console.attach import attach_routes
from console.authoring import check_document, procedure_signatures, read_document, save_document, sysrep_palette
from console.fleet import Fleet, fleet_routes
from console.folded_run import fold_events
from console.procedure_view import procedure_json
from console.proposals import proposal_routes
from console.request_bodies import json_body, second_operator
from console.run_board import RunBoard
from console.sign_in import COOKIE, CSRF_HEADER, SignInRefused, SignIns, WebSession
from console.spatial_api import spatial_routes
from pride.event_words import describe_event
from pride.events import Event, run_start
from pride.phrasing import Wording
from procedure_language.model import Procedure
from procedure_language.parser import load_procedure

__all__ = ["build_app"]

log = logging.getLogger(__name__)

STATIC = Path(__file__).with_name("static")
#: How often a watcher gets fresh telemetry ages and staleness when nothing else changed.
_TELEMETRY_REFRESH_S = 1.0
#: How often the runs list is recomputed when nothing announced a change (a host's lease running out).
_LIST_REFRESH_S = 2.0
#: The runs list and the fleet are read at most this often per page (s).
_LIST_MIN_PERIOD_S = 0.25
#: A run's page is sent its state at most this often (s): a burst of telemetry and events goes out
#: as one update (none is lost: each update carries every event since the last), and the page
#: draws every instruction once per update.
_RUN_MIN_PERIOD_S = 0.2
_CLOSE_POLICY = 1008  # WebSocket close code for "not signed in" (RFC 6455 policy violation)
_CLOSE_ENDED = 1000  # WebSocket close code when the run ended and is now a past run (RFC 6455 normal closure)
_SAFE_METHODS = ("GET", "HEAD")


def _same_origin(connection: HTTPConnection) -> bool:
    """Whether the browser's Origin (when it sends one) is this server: a page elsewhere must not act here."""
    origin = connection.headers.get("origin")
    if origin is None:
        return True  # not a browser's cross-site request (browsers send Origin on POST and WebSocket)
    try:
        return urlsplit(origin).netloc == connection.headers.get("host", "")
    except ValueError:  # a header no browser sends ("http://[x"): not this server
        return False


def _session(request: Request) -> WebSession:
    """The request's session; state-changing requests must also carry its CSRF token."""
    sign_ins: SignIns = request.app.state.sign_ins
    session = sign_ins.session(request)
    if request.method not in _SAFE_METHODS:
        if not _same_origin(request):
            raise ActionRefused(403, "this request came from another site's page: refused")
        if not session.csrf_matches(request.headers.get(CSRF_HEADER)):
            raise ActionRefused(403, f"missing or wrong {CSRF_HEADER}: reload the page")
    return session


def _account(request: Request) -> Account:
    return _session(request).account


def _refusal(exc: ActionRefused | SignInRefused) -> JSONResponse:
    headers = {"Retry-After": str(exc.retry_after)} if isinstance(exc, SignInRefused) and exc.retry_after else None
    details = exc.details if isinstance(exc, ActionRefused) else {}
    return JSONResponse({"error": exc.message, **details}, status_code=exc.status, headers=headers)


#: A route's handler.
Handler = Callable[[Request], Awaitable[Response]]


def _api(handler: Handler) -> Handler:
    """Turn refusals into a JSON error with its status; the page shows the message."""

    async def wrapped(request: Request) -> Response:
        try:
            return await handler(request)
        except (ActionRefused, SignInRefused) as exc:
            return _refusal(exc)

    return wrapped


def _operators(may: str) -> Callable[[Callable[[Request, Account], Awaitable[Response]]], Handler]:
    """The one role check of the console's routes: the handler gets the signed-in operator; an
    observer is refused (403) before the body is read, the message saying what observers ``may``
    do instead ("watch, not act")."""

    def only_operators(handler: Callable[[Request, Account], Awaitable[Response]]) -> Handler:
        async def checked(request: Request) -> Response:
            account = _account(request)
            if not account.may_act:
                raise ActionRefused(403, f"{account.user} is an {account.role.value}: observers may {may}")
            return await handler(request, account)

        return checked

    return only_operators


# ---- pages and session ----------------------------------------------------------------------
async def index(request: Request) -> Response:
    return FileResponse(STATIC / "index.html")


async def favicon(request: Request) -> Response:
    """The icon a browser asks for on its own (a report page names none): not a 404 in every log."""
    return FileResponse(STATIC / "favicon.svg", media_type="image/svg+xml")


def _session_json(session: WebSession) -> dict[str, Any]:
    account = session.account
    return {
        "user": account.user,
        "name": account.name,
        "role": account.role.value,
        "may_act": account.may_act,
        "csrf": session.csrf,
    }


@_api
async def session_get(request: Request) -> Response:
    return JSONResponse(_session_json(_session(request)))


@_api
async def session_post(request: Request) -> Response:
    """Sign in with a user id and password (JSON); the reply carries the CSRF token for later requests."""
    if not _same_origin(request):
        raise ActionRefused(403, "this request came from another site's page: refused")
    body = await json_body(request)
    if not isinstance(body, dict) or not isinstance(body.get("user"), str) or not isinstance(body.get("password"), str):
        raise ActionRefused(400, "expected a JSON object with 'user' and 'password' strings")
    address = request.client.host if request.client else "unknown"
    sign_ins: SignIns = request.app.state.sign_ins
    try:
        session = await run_in_threadpool(sign_ins.sign_in, body["user"].strip(), body["password"], address)
    except SignInRefused as exc:
        log.warning("sign-in refused for %r from %s: %s", body["user"][:64], address, exc.message)
        raise
    response = JSONResponse(_session_json(session))
    response.set_cookie(
        COOKIE,
        session.token,
        max_age=int(sign_ins.limits.absolute),
        httponly=True,
        samesite="strict",
        secure=request.app.state.secure,
    )
    log.info("%s signed in as %s from %s", session.account.user, session.account.role.value, address)
    return response


@_api
async def session_delete(request: Request) -> Response:
    session = _session(request)
    request.app.state.sign_ins.sign_out(session.token)
    response = JSONResponse({"signed_out": True})
    response.delete_cookie(COOKIE, httponly=True, samesite="strict", secure=request.app.state.secure)
    return response


# ---- runs -----------------------------------------------------------------------------------
@_api
async def catalog(request: Request) -> Response:
    _account(request)
    board: RunBoard = request.app.state.board
    return JSONResponse(
        {
            "procedures": board.catalog.procedure_files(),
            "bindings": board.catalog.binding_files(),
            "modes": ["manual", "autonomous"],
        }
    )


@_api
async def runs_list(request: Request) -> Response:
    _account(request)
    board: RunBoard = request.app.state.board
    return JSONResponse({"runs": await run_in_threadpool(board.listing)})


async def _run_request(request: Request, fields: str) -> dict[str, str]:
    """The fields of a request about a run, as strings (mode defaults to manual)."""
    body = await json_body(request)
    if not isinstance(body, dict):
        raise ActionRefused(400, f"expected a JSON object with {fields}")
    return {
        "procedure": str(body.get("procedure", "")),
        "binding": str(body.get("binding", "")),
        "mode": str(body.get("mode", "manual")),
        "take_over": str(body.get("take_over") or ""),
        "onboard": "yes" if body.get("onboard") is True else "",
        "rehearsal": "yes" if body.get("rehearsal") is True else "",
    }


@_api
@_operators("watch, not start runs")
async def runs_start(request: Request, account: Account) -> Response:
    body = await _run_request(request, "procedure, binding and mode")
    board: RunBoard = request.app.state.board
    if body["onboard"]:
        approver = await second_operator(request, account.user)
        run_id = await run_in_threadpool(
            partial(board.start_onboard, rehearsal=bool(body["rehearsal"]), approver=approver),
            account.user,
            body["procedure"],
            body["binding"],
            body["mode"],
        )
        return JSONResponse({"run_id": run_id}, status_code=201)
    live = await run_in_threadpool(
        partial(board.start, take_over=body["take_over"] or None, rehearsal=bool(body["rehearsal"])),
        account.user,
        body["procedure"],
        body["binding"],
        body["mode"],
    )
    return JSONResponse({"run_id": live.run_id}, status_code=201)


def _past_procedure(events: list[Any]) -> Procedure | None:
    start = run_start(events)
    path = start.path if start else None
    if not path or not Path(path).is_file():
        return None
    try:
        return load_procedure(path)
    except Exception:  # the file changed since the run: show the log without the procedure
        log.warning("cannot load %s for a past run", path, exc_info=True)
        return None


def _event_json(event: Event, wording: Wording) -> dict[str, Any]:
    """An audit record for the page: as stored, and its ``summary`` in the procedure view's words
    (the audit panel shows it; the calls as sent are behind the page's raw switch, not here)."""
    return {**event.to_dict(), "summary": describe_event(event, wording)}


def _run_view(board: RunBoard, run_id: str) -> dict[str, Any]:
    run = board.view(run_id)
    sysreps = board.sysreps()
    if run is not None:
        return {
            "procedure": run.procedure_view,
            "state": run.state_json(),
            "server_time": time.time(),
            "events": [_event_json(e, Wording(sysreps)) for e in run.events_since(0)],
            "telemetry": run.telemetry_json(),
        }
    events = board.past_events(run_id)
    procedure = _past_procedure(events)
    state = {**fold_events(run_id, events, sysreps).to_dict(), "live": False}
    record = board.host_record(run_id)
    if record is not None and state["status"] not in ("completed", "stopped"):  # its host died or lost the database
        state["host_lost"] = {"host": record.host, "since": record.lease_until.isoformat()}
    return {
        "procedure": procedure_json(procedure, sysreps=sysreps) if procedure else None,
        "state": state,
        "server_time": time.time(),
        "events": [_event_json(e, Wording(sysreps)) for e in events],
        "telemetry": {"readings": [], "checks": {}},
    }


@_api
async def run_get(request: Request) -> Response:
    _account(request)
    return JSONResponse(await run_in_threadpool(_run_view, request.app.state.board, request.path_params["run_id"]))


@_api
async def run_action(request: Request) -> Response:  # the board refuses an observer, and records it in the run
    account, board = _account(request), request.app.state.board
    action = ActionRequest.from_json(await json_body(request))
    result = await run_in_threadpool(board.act, request.path_params["run_id"], account, action)
    return JSONResponse({"ok": True, "action": action.action, "result": result})


@_api
async def run_action_progress(request: Request) -> Response:
    """What became of an action forwarded to a far host (one answered "on its way, expected at T")."""
    _account(request)
    board: RunBoard = request.app.state.board
    run_id, request_id = request.path_params["run_id"], request.path_params["request_id"]
    known = await run_in_threadpool(board.forwarding.progress, request_id, run_id)
    if known is None:
        raise ActionRefused(404, f"run {run_id!r} has no forwarded action {request_id}")
    return JSONResponse(known)


@_api
@_operators("watch, not resume runs")
async def run_resume(request: Request, account: Account) -> Response:
    """Continue a stopped or interrupted run (what ``caretaker run --resume`` does) on a binding."""
    body = await _run_request(request, "binding and mode")
    board: RunBoard = request.app.state.board
    live = await run_in_threadpool(
        board.resume, account.user, request.path_params["run_id"], body["binding"], body["mode"]
    )
    return JSONResponse({"run_id": live.run_id})


@_api
async def run_camera(request: Request) -> Response:
    _account(request)
    board: RunBoard = request.app.state.board
    run_id = request.path_params["run_id"]
    run = await run_in_threadpool(board.view, run_id)
    image = await run_in_threadpool(run.camera_image) if run else _past_image(board, run_id)
    if image is None:
        raise ActionRefused(404, "no camera image yet: no command result named a PNG and the live feed captured none")
    if isinstance(image, bytes):  # copied into the database by the console that hosts the run
        return Response(image, media_type="image/png", headers={"Cache-Control": "no-store"})
    if not image.is_file():
        raise ActionRefused(404, f"the camera image {image} does not exist on this server")
    return FileResponse(image, media_type="image/png", headers={"Cache-Control": "no-store"})


def _past_image(board: RunBoard, run_id: str) -> Path | None:
    image = fold_events(run_id, board.past_events(run_id)).latest_image
    return Path(image) if image else None


# ---- live updates ---------------------------------------------------------------------------
async def _socket_account(websocket: WebSocket) -> Account | None:
    """The signed-in account opening a WebSocket from this site's page; None after closing it (refused)."""
    try:
        if not _same_origin(websocket):
            raise SignInRefused(403, "this connection came from another site's page")
        sign_ins: SignIns = websocket.app.state.sign_ins
        return sign_ins.session(websocket).account
    except SignInRefused as exc:
        await websocket.close(code=_CLOSE_POLICY, reason=exc.message)
        return None


async def _still_signed_in(websocket: WebSocket) -> bool:
    """An open console is in use; a session that ended closes its connection."""
    try:
        await run_in_threadpool(websocket.app.state.sign_ins.session, websocket)
    except SignInRefused as exc:
        await websocket.close(code=_CLOSE_POLICY, reason=exc.message)
        return False
    return True


async def run_socket(websocket: WebSocket) -> None:
    """Push the run's state, new audit events and telemetry to one browser until it leaves or its session ends.

    The run may be hosted here or by another console: then each wake-up first reads what the
    database has new (:meth:`RemoteRun.refresh`).
    """
    account = await _socket_account(websocket)
    if account is None:
        return
    board: RunBoard = websocket.app.state.board
    run = await run_in_threadpool(board.view, websocket.path_params["run_id"])
    if run is None:
        await websocket.close(code=_CLOSE_POLICY, reason="that run is not live on any console")
        return
    wording = Wording(await run_in_threadpool(board.sysreps))
    await websocket.accept()
    watcher = run.watch(account)
    receiver = asyncio.create_task(_drain(websocket))
    try:
        while not receiver.done():
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(watcher.changed.wait(), _TELEMETRY_REFRESH_S)
            watcher.changed.clear()
            await run_in_threadpool(run.refresh)
            if run.retired:  # the page reloads it as a past run (its last state is in the log)
                await websocket.close(code=_CLOSE_ENDED, reason="the run ended")
                return
            if not await _still_signed_in(websocket):
                return
            read_at = time.monotonic()
            state, telemetry = await run_in_threadpool(lambda: (run.state_json(), run.telemetry_json()))
            events = run.events_since(watcher.sent_seq)
            if events:
                watcher.sent_seq = events[-1].seq
            await websocket.send_json(
                {
                    "type": "update",
                    "state": state,
                    "events": [_event_json(e, wording) for e in events],
                    "telemetry": telemetry,
                    "server_time": time.time(),
                }
            )
            await asyncio.sleep(max(0.0, read_at + _RUN_MIN_PERIOD_S - time.monotonic()))
    except (WebSocketDisconnect, RuntimeError):
        pass  # the browser left (RuntimeError: send after the client closed)
    finally:
        run.unwatch(watcher)
        board.let_go(run)
        receiver.cancel()


async def runs_socket(websocket: WebSocket) -> None:
    """Push the runs list whenever it changes (a run started, ended, moved host, or its host went silent),
    and the fleet whenever a robot's row changes (fleet.py)."""
    account = await _socket_account(websocket)
    if account is None:
        return
    board: RunBoard = websocket.app.state.board
    fleet: Fleet = websocket.app.state.fleet
    await websocket.accept()
    watcher = board.list_watchers.add(account)
    receiver = asyncio.create_task(_drain(websocket))
    sent: dict[str, list[dict[str, Any]]] = {}
    try:
        while not receiver.done():
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(watcher.changed.wait(), _LIST_REFRESH_S)  # leases run out unannounced
            watcher.changed.clear()
            if not await _still_signed_in(websocket):
                return
            read_at = time.monotonic()
            for kind, read in (("runs", board.listing), ("robots", fleet.read)):
                now = await run_in_threadpool(read)
                if now != sent.get(kind):
                    await websocket.send_json({"type": "fleet" if kind == "robots" else "runs", kind: now})
                    sent[kind] = now
            # every live run republishes each second: with fifty, read at most this often, whatever woke it
            await asyncio.sleep(max(0.0, read_at + _LIST_MIN_PERIOD_S - time.monotonic()))
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        board.list_watchers.remove(watcher)
        receiver.cancel()


async def _drain(websocket: WebSocket) -> None:
    """Read until the browser disconnects (it sends nothing else; actions go over HTTP)."""
    while True:
        message = await websocket.receive()
        if message["type"] == "websocket.disconnect":
            return


# ---- reports --------------------------------------------------------------------------------
@_api
async def run_report(request: Request) -> Response:
    """The after-action report of a run, written by pride's report module (caretaker report)."""
    _account(request)
    board: RunBoard = request.app.state.board
    run_id = request.path_params["run_id"]
    board.past_events(run_id)  # 404 for unknown runs
    writer = request.app.state.report_writer
    if writer is None:
        raise ActionRefused(501, "this installation has no report writer (pride.report); use `caretaker report RUN`")
    path = await run_in_threadpool(writer, run_id, Wording(board.sysreps()))
    return FileResponse(path, media_type="text/html")


# ---- authoring ------------------------------------------------------------------------------
async def author_page(request: Request) -> Response:
    return FileResponse(STATIC / "author.html")


@_api
async def author_palette(request: Request) -> Response:
    _account(request)
    board: RunBoard = request.app.state.board
    sysreps = await run_in_threadpool(board.sysreps)
    procedures = board.catalog.procedure_files()
    signatures = await run_in_threadpool(procedure_signatures, board.catalog.procedures, procedures)
    return JSONResponse({"sysreps": sysrep_palette(sysreps), "procedures": procedures, "signatures": signatures})


@_api
async def author_open(request: Request) -> Response:
    _account(request)
    board: RunBoard = request.app.state.board
    path = board.catalog.procedure_path(request.path_params["name"])
    return JSONResponse(await run_in_threadpool(read_document, path))


def _document(body: Any) -> dict[str, Any]:
    if not isinstance(body, dict) or not isinstance(body.get("document"), dict):
        raise ActionRefused(400, "expected a JSON object with a 'document'")
    document: dict[str, Any] = body["document"]
    return document


@_api
async def author_check(request: Request) -> Response:
    _account(request)
    board: RunBoard = request.app.state.board
    document = _document(await json_body(request))
    checked = await run_in_threadpool(check_document, document, board.catalog.procedures, board.sysreps())
    return JSONResponse(checked)


@_api
@_operators("read procedures, not save them")
async def author_save(request: Request, account: Account) -> Response:
    board: RunBoard = request.app.state.board
    body = await json_body(request)
    document = _document(body)
    saved = await run_in_threadpool(
        lambda: save_document(
            document,
            str(body.get("name", "")),
            board.catalog.procedures,
            board.sysreps(),
            replace=body.get("replace") is True,
        )
    )
    log.info("%s saved procedure %s", account.user, saved["saved"])
    await run_in_threadpool(board.release_desk.saved, account.user, saved["saved"])
    return JSONResponse(saved)


@_api
async def author_version(request: Request) -> Response:
    """Where a procedure's file stands: its version's hash, its newest release, a request for one."""
    _account(request)
    board: RunBoard = request.app.state.board
    return JSONResponse(await run_in_threadpool(board.release_desk.version_state, request.path_params["name"]))


@_api
@_operators("read procedures, not release them")
async def author_release(request: Request, account: Account) -> Response:
    """``{"action": "request" | "release", "sha256": the version the operator saw}``: ask a second
    operator to review and release it, or (as that second operator) release it."""
    board: RunBoard = request.app.state.board
    body = await json_body(request)
    if not isinstance(body, dict) or body.get("action") not in ("request", "release"):
        raise ActionRefused(400, 'expected {"action": "request" or "release", "sha256": the version you reviewed}')
    seen = str(body.get("sha256", ""))
    act = board.release_desk.ask_release if body["action"] == "request" else board.release_desk.release
    state = await run_in_threadpool(act, account.user, request.path_params["name"], seen)
    log.info("%s: %s of %s (sha256 %s)", account.user, body["action"], request.path_params["name"], seen)
    return JSONResponse(state)


def build_app(
    board: RunBoard,
    sign_ins: SignIns,
    *,
    report_writer: Callable[[str, Wording], Path] | None = None,
    secure: bool = False,
) -> Starlette:
    """The Starlette app; at shutdown it stops its live runs (resumable) and closes their gateways.
    ``secure``: served over TLS, so the session cookie is marked Secure (never sent in clear text)."""

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        try:
            yield
        finally:
            await run_in_threadpool(board.close)
            await run_in_threadpool(proposals.close)

    proposals, proposal_api = proposal_routes(board, api=_api, account=_account, operators=_operators)
    fleet = Fleet(board.catalog, board.hosting)
    app = Starlette(
        routes=[
            Route("/", index),
            Route("/runs/{run_id}/report", run_report),
            Route("/author", author_page),
            Route("/api/author/palette", author_palette),
            Route("/api/author/procedures/{name}", author_open),
            Route("/api/author/check", author_check, methods=["POST"]),
            Route("/api/author/save", author_save, methods=["POST"]),
            Route("/api/author/procedures/{name}/version", author_version),
            Route("/api/author/procedures/{name}/release", author_release, methods=["POST"]),
            Route("/api/session", session_get, methods=["GET"]),
            Route("/api/session", session_post, methods=["POST"]),
            Route("/api/session", session_delete, methods=["DELETE"]),
            Route("/api/catalog", catalog),
            Route("/api/runs", runs_list, methods=["GET"]),
            Route("/api/runs", runs_start, methods=["POST"]),
            Route("/api/runs/{run_id}", run_get),
            Route("/api/runs/{run_id}/actions", run_action, methods=["POST"]),
            Route("/api/runs/{run_id}/actions/{request_id:int}", run_action_progress),
            Route("/api/runs/{run_id}/resume", run_resume, methods=["POST"]),
            Route("/api/runs/{run_id}/camera", run_camera),
            WebSocketRoute("/ws/runs", runs_socket),
            WebSocketRoute("/ws/runs/{run_id}", run_socket),
            *spatial_routes(account=_account, api=_api, same_origin=_same_origin),  # the 3D view (spatial_api.py)
            *attach_routes(api=_api, operators=_operators),  # a new supervisor for an onboard run (attach.py)
            *proposal_api,  # agents' proposals, accepted or declined (proposals.py)
            *fleet_routes(fleet, api=_api, account=_account),  # every robot and its run (fleet.py)
            Route("/favicon.ico", favicon),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        lifespan=lifespan,
    )
    app.state.board = board
    app.state.fleet = fleet
    app.state.sign_ins = sign_ins
    app.state.report_writer = report_writer
    app.state.secure = secure
    return app
