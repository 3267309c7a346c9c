"""The fleet at a glance: every robot and its live run, the ones that need an operator first.

A ground supervises many robots; an operator must see at once which one waits for them. Every
live run, whoever hosts it (this console, another, a supervisor of an onboard run), publishes its
view in ``run_hosts`` (:mod:`ground.run_hosts`), so one query gives the whole fleet, and the
console folds nothing per run. A robot with no live run is listed as idle, from the bindings.

The order is what needs an operator: a run holding for one (a question, a confirmation, an
approval, a halt, an unknown outcome), then a run whose host is gone, then a run whose robot link
or habitat is silent, then limits out, then runs going on, then idle robots; within each, the
longest waiting first.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import BaseRoute, Route

from console.accounts import Account
from console.catalog import Catalog
from datafile import DataFileError
from ground.run_hosts import HostRecord, RunHosting
from procedure_language.binding import read_binding

__all__ = ["Fleet", "FleetEntry", "fleet_entries", "fleet_routes"]

Handler = Callable[[Request], Any]

#: What needs an operator, most urgent first (:attr:`FleetEntry.urgency` is the index).
URGENCY = ("holds for an operator", "host lost", "link silent", "limits out", "running", "idle")


@dataclass(frozen=True)
class FleetEntry:
    """One robot as the fleet view shows it. ``needs``: what an operator must do, in words ("" for none)."""

    robot: str
    bindings: tuple[str, ...]
    urgency: int  # an index into URGENCY: the lower, the sooner an operator should look
    run_id: str = ""
    procedure: str = ""
    status: str = ""
    mode: str = ""
    started_by: str = ""
    host: str = ""
    instruction: str = ""
    needs: str = ""
    since: str = ""  # since when it is as it is (ISO), when the run says
    link: str = ""  # the robot link's (ground run) or the habitat's (onboard run) state in words
    heard: str = ""  # an onboard run: when the ground last heard from the habitat (ISO)
    limits_out: tuple[str, ...] = ()  # SYSTEM.ITEM is RED HIGH, ...
    onboard: bool = False

    @property
    def state(self) -> str:
        """URGENCY's words for it."""
        return URGENCY[self.urgency]

    def to_json(self) -> dict[str, Any]:
        return {
            **asdict(self),
            "state": self.state,
            "bindings": list(self.bindings),
            "limits_out": list(self.limits_out),
        }


def _needs(state: dict[str, Any]) -> str:
    """What the run waits for from an operator, in words ("" when it waits for nobody)."""
    hold, reason = state.get("hold"), str(state.get("reason") or "")
    if state.get("approval") and hold == "approval":
        return "a second operator's approval" + (f": {reason}" if reason else "")
    if hold:
        return f"{str(hold).replace('_', ' ')}" + (f": {reason}" if reason else "")
    if state.get("status") == "awaiting" or state.get("awaiting"):
        return str(state.get("awaiting") or "an operator")
    onboard = state.get("onboard")
    if isinstance(onboard, dict) and onboard.get("waiting"):
        return str(onboard["waiting"])
    return ""


def _limits_out(telemetry: dict[str, Any]) -> tuple[str, ...]:
    out = []
    for reading in telemetry.get("readings", []):
        limit = reading.get("limit")
        if isinstance(limit, dict) and limit.get("state") in ("yellow", "red"):
            out.append(f"{reading.get('system')}.{reading.get('item')} {limit.get('words') or limit['state']}")
    return tuple(out)


def _link(state: dict[str, Any]) -> tuple[str, bool]:
    """The link in words, and whether it is down (a robot link lost, a habitat silent)."""
    link = state.get("link")
    if not isinstance(link, dict) or link.get("state") in (None, "connected"):
        return "connected", False
    since = f" since {link['since']}" if link.get("since") else ""
    return f"{link['state']}{since}", True


def _part(view: dict[str, Any], key: str) -> dict[str, Any]:
    """``view[key]`` if it is an object (a host of another version may publish less), else empty."""
    part = view.get(key)
    return part if isinstance(part, dict) else {}


def _entry(robot: str, bindings: tuple[str, ...], record: HostRecord, view: dict[str, Any]) -> FleetEntry:
    state = _part(view, "state")
    needs, limits = _needs(state), _limits_out(_part(view, "telemetry"))
    link, down = _link(state)
    onboard = _part(state, "onboard") if "onboard" in state else None
    urgency = (bool(needs), not record.alive, down, bool(limits), True).index(True)  # URGENCY's order
    return FleetEntry(
        robot=robot,
        bindings=bindings,
        urgency=urgency,
        run_id=record.run_id,
        procedure=str(state.get("procedure") or ""),
        status=record.status,
        mode=record.mode,
        started_by=record.started_by,
        host=record.host,
        instruction=str(state.get("current") or ""),
        needs=needs,
        since=str(state.get("arrived") or record.claimed.isoformat()),
        link=link,
        heard=str(onboard.get("heard") or "") if onboard else "",
        limits_out=limits,
        onboard=onboard is not None,
    )


def fleet_entries(
    robots: dict[str, tuple[str, ...]], hosted: Iterable[tuple[HostRecord, dict[str, Any]]]
) -> list[FleetEntry]:
    """Every robot of ``robots`` (robot -> its binding files) with its live runs (``hosted``: each run's
    host row and published view), most urgent first; a run on a binding not in ``robots`` is listed
    under its binding's name. A robot with several live runs (one controls it, others wait) has a row each."""
    robot_of = {binding: robot for robot, bindings in robots.items() for binding in bindings}
    entries, busy = [], set()
    for record, view in hosted:
        robot = robot_of.get(record.binding) or str(_part(view, "state").get("robot") or "") or record.binding
        busy.add(robot)
        entries.append(_entry(robot, robots.get(robot, (record.binding,)), record, view))
    entries += [
        FleetEntry(robot, bindings, len(URGENCY) - 1) for robot, bindings in robots.items() if robot not in busy
    ]
    # the longest waiting first within a rank (an ISO time sorts as the time); idle ones by name
    return sorted(entries, key=lambda e: (e.urgency, e.since or "~", e.robot))


@lru_cache(maxsize=256)
def _robot_named(path: Path, _modified: int) -> str:
    """The robot a binding file names (read again when the file changes)."""
    try:
        return read_binding(path).robot
    except (DataFileError, OSError):  # listed under its file name here; a start on it says what is wrong
        return path.stem


def _robots(catalog: Catalog) -> dict[str, tuple[str, ...]]:
    robots: dict[str, list[str]] = {}
    for name in catalog.binding_files():
        path = catalog.bindings / name
        try:
            robot = _robot_named(path, path.stat().st_mtime_ns)
        except FileNotFoundError:  # removed since it was listed
            continue
        robots.setdefault(robot, []).append(name)
    return {robot: tuple(bindings) for robot, bindings in sorted(robots.items())}


class Fleet:
    """The fleet as a console reads it: its bindings' robots and every hosted run, in one query."""

    def __init__(self, catalog: Catalog, hosting: RunHosting) -> None:
        self._catalog = catalog
        self._hosting = hosting

    def read(self) -> list[dict[str, Any]]:
        """Every robot's entry as JSON, most urgent first."""
        hosted, _ = self._hosting.views()
        return [entry.to_json() for entry in fleet_entries(_robots(self._catalog), hosted)]


def fleet_routes(
    fleet: Fleet, *, api: Callable[[Handler], Handler], account: Callable[[Request], Account]
) -> list[BaseRoute]:
    """``GET /api/fleet``: ``{"robots": [entry, ...]}``, most urgent first (any signed-in role). A console's
    page has it pushed on the runs list's socket instead (``{"type": "fleet", ...}``, app.py)."""

    @api
    async def listing(request: Request) -> Response:
        account(request)
        return JSONResponse({"robots": await run_in_threadpool(fleet.read)})

    return [Route("/api/fleet", listing)]
