"""The 3D view's routes: its own WebSocket (scene document, then updates) and the drag.

``/ws/runs/{run_id}/spatial`` pushes what :class:`console.spatial_feed.SpatialFeed` keeps of the
habitat (one feed per live run, shared by its browsers, closed with its last one);
``/api/runs/{run_id}/spatial/camera`` is the robot camera's newest image from that feed.
``POST /api/runs/{run_id}/spatial/pose`` is a registration drag: operators only (403 for an
observer, checked before the body is read), CSRF like every change, sent as that operator through
the run's executive (:meth:`pride.executive.Executive.operator_command`) so the audit log records
who moved what where; a refused one (an observer's, one the run cannot take now) is recorded too.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable
from typing import Any

from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection, Request
from starlette.responses import JSONResponse, Response
from starlette.routing import BaseRoute, Route, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from console.accounts import Account
from console.actions import ActionRefused, record_refused
from console.camera_feed import MOTION_COMMAND
from console.live_run import LiveRun
from console.run_board import RunBoard
from console.sign_in import SignInRefused, SignIns
from console.spatial_feed import AT_COMMANDS_THAT_MOVE_TEMPLATES, LOCATE_COMMAND, PUSH_INTERVAL_S, SpatialFeed
from console.spatial_link import read_view_link
from pride import systems
from pride.event_payloads import CommandResult, CommandSent
from pride.events import Event
from pride.states import OperatorActionError, RefusalRule
from procedure_language.sysrep import SysRep

__all__ = ["POSE_COMMANDS", "spatial_routes"]

log = logging.getLogger(__name__)

POSE_COMMANDS = ("set_display_object_pose", "set_waypoint_pose")
"""The commands a drag may send (with exactly the arguments the run's AT SysRep declares)."""

_CLOSE_POLICY = 1008
_CLOSE_ENDED = 1000
_SESSION_CHECK_S = 5.0


class SpatialFeeds:
    """The feeds of the live runs that someone views in 3D, by run id."""

    def __init__(self) -> None:
        self._feeds: dict[str, tuple[SpatialFeed, LiveRun, Callable[[Any], None]]] = {}
        self._users: dict[str, int] = {}

    async def open(self, board: RunBoard, live: LiveRun) -> SpatialFeed | None:
        """The run's feed (made on first use), or None when its binding has no AT system."""
        run_id = live.run_id
        if run_id not in self._feeds:
            path = board.catalog.binding_path(live.binding)
            link = await run_in_threadpool(read_view_link, path, rosbridge_url=board.rosbridge_url_for(live.binding))
            if link is None:
                return None
            if run_id not in self._feeds:  # (another browser may have made it meanwhile)
                feed = SpatialFeed(
                    link, camera_url=f"/api/runs/{run_id}/spatial/camera", camera=board.camera.camera_for(live.binding)
                )
                feed.start()
                loop = asyncio.get_running_loop()

                def on_event(event: Event) -> None:  # the executive's thread: an AT command sent or ended
                    data = event.data
                    if _locate(event):
                        loop.call_soon_threadsafe(feed.locate_sent)
                    if not isinstance(data, (CommandSent, CommandResult)):
                        return
                    command, args = data.command, data.args
                    motion = (data.system, command) == MOTION_COMMAND
                    if isinstance(data, CommandSent) and motion:
                        sent = (str(args.get("affordance_template", "")), str(args.get("trajectory", "")))
                        loop.call_soon_threadsafe(feed.command_sent, *sent)
                    elif isinstance(data, CommandResult) and motion:
                        loop.call_soon_threadsafe(feed.command_ended)
                    elif isinstance(data, CommandResult) and command in AT_COMMANDS_THAT_MOVE_TEMPLATES:
                        if command == "set_display_object_pose" and data.success is True:
                            loop.call_soon_threadsafe(feed.registered, dict(args))
                        loop.call_soon_threadsafe(feed.refresh)

                live.executive.add_listener(on_event)
                if any(_locate(e) for e in live.events_since(0)):  # before the feed: its latched result is this run's
                    feed.locate_sent()
                self._feeds[run_id] = (feed, live, on_event)
        self._users[run_id] = self._users.get(run_id, 0) + 1
        return self._feeds[run_id][0]

    def feed(self, run_id: str) -> SpatialFeed | None:
        entry = self._feeds.get(run_id)
        return entry[0] if entry else None

    async def release(self, run_id: str) -> None:
        self._users[run_id] = self._users.get(run_id, 1) - 1
        if self._users[run_id] > 0 or run_id not in self._feeds:
            return
        feed, live, on_event = self._feeds.pop(run_id)
        del self._users[run_id]
        live.executive.remove_listener(on_event)
        await feed.close()


async def _moved(request: Request, user: Account, live: LiveRun) -> tuple[str, systems.CommandResult]:
    """The drag's command, sent through the run as ``user``, and its result; ActionRefused says why not."""
    if not user.may_act:  # refused before the body is even read
        raise ActionRefused(
            403,
            f"{user.user} is an {user.role.value}: observers may watch the 3D view, not move things",
            rule=RefusalRule.OBSERVERS_WATCH,
        )
    try:
        body = await request.json()
    except ValueError:
        raise ActionRefused(400, "the request body must be JSON") from None
    system, sysrep = _at_system(live)
    command, args = _pose_command(body, sysrep)
    try:
        return command, await run_in_threadpool(live.executive.operator_command, user.user, system, command, args)
    except OperatorActionError as exc:
        raise ActionRefused(409, str(exc), rule=exc.rule) from None


def _locate(event: Event) -> bool:
    data = event.data
    return isinstance(data, CommandSent) and (data.system, data.command) == LOCATE_COMMAND


def spatial_routes(
    *,
    account: Callable[[Request], Account],
    api: Callable[[Callable[[Request], Any]], Any],
    same_origin: Callable[[HTTPConnection], bool],
) -> list[BaseRoute]:
    """The routes, given the app's session check (``account``), refusal handling (``api``) and
    Origin check, so every request here is checked exactly as the rest of the page's."""
    feeds = SpatialFeeds()

    async def pose(request: Request) -> Response:
        user = account(request)
        board: RunBoard = request.app.state.board
        live = board.live(request.path_params["run_id"])
        if live is None:  # a run hosted by another console is moved from that console
            raise ActionRefused(404, f"run {request.path_params['run_id']!r} is not live on this console")
        try:
            command, result = await _moved(request, user, live)
        except ActionRefused as exc:  # a refused move is on the run's record, as every refused act
            await run_in_threadpool(record_refused, live.executive, user.user, "move", exc)
            raise
        outcome = result.outcome.value
        return JSONResponse(
            {"ok": True, "command": command, "outcome": outcome, "success": result.success, "message": result.message}
        )

    async def socket(websocket: WebSocket) -> None:
        sign_ins: SignIns = websocket.app.state.sign_ins
        try:
            if not same_origin(websocket):
                raise SignInRefused(403, "this connection came from another site's page")
            sign_ins.session(websocket)
        except SignInRefused as exc:
            await websocket.close(code=_CLOSE_POLICY, reason=exc.message)
            return
        board: RunBoard = websocket.app.state.board
        run_id = websocket.path_params["run_id"]
        live = board.live(run_id)
        if live is None:
            await websocket.close(code=_CLOSE_POLICY, reason="that run is not live on this server")
            return
        await websocket.accept()
        try:
            feed = await feeds.open(board, live)
        except Exception as exc:  # a binding that cannot be read: said to the page, never a traceback
            log.exception("3D view of run %s", run_id)
            await websocket.send_json({"type": "none", "message": f"no 3D view: {type(exc).__name__}: {exc}"})
            await websocket.close()
            return
        if feed is None:
            await websocket.send_json(
                {"type": "none", "message": f"binding {live.binding} has no Affordance Template system to show"}
            )
            await websocket.close()
            return
        watcher = feed.watch()
        receiver = asyncio.create_task(_drain(websocket))
        checked = time.monotonic()
        try:
            while not receiver.done():
                with contextlib.suppress(asyncio.TimeoutError):
                    await asyncio.wait_for(watcher.changed.wait(), 1.0)
                if live.retired:
                    await websocket.close(code=_CLOSE_ENDED, reason="the run ended")
                    return
                if time.monotonic() - checked > _SESSION_CHECK_S:  # an ended session closes the view too
                    checked = time.monotonic()
                    try:
                        await run_in_threadpool(sign_ins.session, websocket)
                    except SignInRefused as exc:
                        await websocket.close(code=_CLOSE_POLICY, reason=exc.message)
                        return
                document, updates = watcher.take()
                if document is not None:
                    await websocket.send_json({"type": "scene", "document": document})
                for update in updates:
                    await websocket.send_json({"type": "update", "update": update})
                await asyncio.sleep(
                    PUSH_INTERVAL_S
                )  # the bound on the push rate; newer updates replace older meanwhile
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            feed.unwatch(watcher)
            receiver.cancel()
            await feeds.release(run_id)

    async def camera(request: Request) -> Response:
        account(request)
        feed = feeds.feed(request.path_params["run_id"])
        if feed is None or feed.camera_png is None:
            raise ActionRefused(404, "no robot camera image yet (it comes with the 3D view's feed of a live run)")
        return Response(feed.camera_png, media_type="image/png", headers={"Cache-Control": "no-store"})

    return [
        Route("/api/runs/{run_id}/spatial/pose", api(pose), methods=["POST"]),
        Route("/api/runs/{run_id}/spatial/camera", api(camera)),
        WebSocketRoute("/ws/runs/{run_id}/spatial", socket),
    ]


def _pose_command(body: Any, sysrep: SysRep) -> tuple[str, dict[str, Any]]:
    """The command and its arguments, exactly those the SysRep declares (the gateway checks types)."""
    if not isinstance(body, dict) or not isinstance(body.get("args"), dict):
        raise ActionRefused(400, "expected a JSON object with command and args")
    command = str(body.get("command", ""))
    declared = sysrep.command(command) if command in POSE_COMMANDS else None
    if declared is None:
        raise ActionRefused(400, f"unknown pose command {command!r}; expected {' or '.join(POSE_COMMANDS)}")
    args: dict[str, Any] = body["args"]
    expected = {a.name for a in declared.args}
    if set(args) != expected:
        missing, extra = sorted(expected - set(args)), sorted(set(args) - expected)
        raise ActionRefused(
            400,
            f"{command}: "
            + "; ".join(
                part
                for part in (
                    f"missing {', '.join(missing)}" if missing else "",
                    f"unknown {', '.join(extra)}" if extra else "",
                )
                if part
            ),
        )
    return command, args


def _at_system(live: LiveRun) -> tuple[str, SysRep]:
    """The run's SysRep that takes pose commands (the Affordance Template one), by its id in the run."""
    for system_id, sysrep in live.sysreps.items():
        if all(sysrep.command(c) is not None for c in POSE_COMMANDS):
            return system_id, sysrep
    raise ActionRefused(409, "this run's procedure uses no Affordance Template system: nothing to register")


async def _drain(websocket: WebSocket) -> None:
    while True:
        message = await websocket.receive()
        if message["type"] == "websocket.disconnect":
            return
