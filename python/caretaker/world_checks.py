"""World checks as data: what ``caretaker demo`` verifies of the world, measured by the simulator.

A procedure that says COMPLETED while the filter is still in the wrong place is a failed demo,
so a deployment's ``demo.checks`` states what must hold, as data, and the demo measures it
against the simulation's ground truth (``sim/check/frames`` and ``sim/frames`` through
rosbridge, the robot side's telemetry topics, the run's audit log), never the procedure's word
for it::

    checks:
      - {object: filter/CDRA-F-0007, at: rack/slot_3, within_mm: 30}        # where an object ended
      - {tool: tool0, visits: {frame: robot_base, xyz: [0.5, 0, 0.4], rpy: [0, 3.1416, 0]},
         within_mm: 5, within_deg: 2}                                       # a pose the tool reached
      - {topic: cdra/installed_filter_id, equals: "${clean_filter_id}"}      # a telemetry value
      - {images_of: every target}                                            # the run's captures

``at`` is the end of the run, measured where everything really is (``sim/check/frames``: on a
displaced world ``sim/frames`` says where the drawings put a seated filter, not where it is);
``visits`` is any moment of it (``sim/frames`` is watched from before the procedure starts: the
robot's own frames are the same in both). A place is a ``sim/frames`` name, or a pose ``{frame, xyz, rpy}`` in one
(``frame`` defaults to ``world``); ``within_deg`` also checks the orientation. A relative topic
name is in the deployment's namespace; ``${name}`` is the demo's input of that name. Every
mistake is a ``file:line: key: problem`` when the deployment loads, and the frames and targets
named are checked against the deployment's scene there too.
"""

from __future__ import annotations

import asyncio
import math
import re
import threading
import time
from collections.abc import Callable, Coroutine, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from at_ros.transforms import angle_between, from_xyz_quat, from_xyz_rpy
from datafile import Field
from datafile.urdf import read_urdf
from rosbridge_wire.client import Endpoint, LinkError, RosbridgeClient, Subscription
from sim.scene import Scene

__all__ = [
    "FrameCheck",
    "ImagesCheck",
    "Place",
    "TelemetryCheck",
    "Verdict",
    "WorldCheck",
    "WorldWatch",
    "check_against_scene",
    "load_checks",
    "scene_frames",
    "watch_world",
]

#: What a check item names, one per item: the key decides the kind of check.
SUBJECTS = ("object", "tool", "topic", "images_of")
EVERY_TARGET = "every target"
_INPUT = re.compile(r"\$\{([^}]*)\}")
#: s to wait for a latched topic or the simulation's frames through rosbridge: they answer at once
#: when they exist; the rest is room for a machine so crowded that any answer takes tens of seconds.
TOPIC_TIMEOUT = 60.0
#: s between asking the simulation's check service again while it is not found yet.
ASK_AGAIN_S = 0.5

T = TypeVar("T")


@dataclass(frozen=True)
class Place:
    """Where a frame should be: a ``sim/frames`` frame itself, or a pose given in one."""

    frame: str  # a sim/frames name, or "world"
    xyz: tuple[float, ...] = (0.0, 0.0, 0.0)
    rpy: tuple[float, ...] = (0.0, 0.0, 0.0)
    named: bool = True  # written as the frame's name alone

    def words(self) -> str:
        if self.named:
            return self.frame
        mm = ", ".join(f"{v * 1000:.0f}" for v in self.xyz)
        return f"({mm}) mm in {self.frame}"

    def world(self, frames: dict[str, np.ndarray]) -> np.ndarray:
        base = np.eye(4) if self.frame == "world" else frames[self.frame]
        pose: np.ndarray = base @ from_xyz_rpy(self.xyz, self.rpy)
        return pose


@dataclass(frozen=True)
class FrameCheck:
    """A frame of the world (an object, or the tool) at a place: at the run's end, or at some moment of it."""

    subject: str  # its sim/frames name
    place: Place
    within_mm: float
    within_deg: float | None  # None: the position only
    during_run: bool  # ``visits``: at any moment; ``at``: at the end

    def errors(self, frames: dict[str, np.ndarray]) -> tuple[float, float]:
        """(mm, degrees) between the subject and its place in one sample of the frames."""
        subject, place = frames[self.subject], self.place.world(frames)
        return float(np.linalg.norm(subject[:3, 3] - place[:3, 3])) * 1000, math.degrees(angle_between(subject, place))

    def holds(self, mm: float, deg: float) -> bool:
        return mm <= self.within_mm and (self.within_deg is None or deg <= self.within_deg)

    def measure(self, mm: float, deg: float) -> str:
        """'4 mm, 0.3° from it (within 30 mm, 2°)': what was measured against what is allowed."""
        if self.within_deg is None:
            return f"{mm:.0f} mm from it (within {self.within_mm:g} mm)"
        return f"{mm:.0f} mm, {deg:.1f}° from it (within {self.within_mm:g} mm, {self.within_deg:g}°)"


@dataclass(frozen=True)
class TelemetryCheck:
    """A telemetry topic's value (its ``data``) at the end of the run."""

    topic: str  # as written: a relative name is in the deployment's namespace
    expected: str | bool | int | float

    def matches(self, value: Any) -> bool:
        if isinstance(self.expected, bool) or isinstance(value, bool):
            return value is self.expected
        if isinstance(self.expected, (int, float)):
            return isinstance(value, (int, float)) and math.isclose(value, self.expected, abs_tol=1e-9)
        return bool(value == self.expected)


@dataclass(frozen=True)
class ImagesCheck:
    """The run captured a non-empty image of each target (its camera commands' ``label``)."""

    targets: tuple[str, ...] | None  # None: every target of the scene


WorldCheck = FrameCheck | TelemetryCheck | ImagesCheck


@dataclass(frozen=True)
class Verdict:
    """One check's outcome, in words with rounded values (the demo prints one line per check)."""

    holds: bool
    words: str


# --- reading ------------------------------------------------------------------------------------


def load_checks(f: Field, inputs: dict[str, str]) -> tuple[WorldCheck, ...]:
    """The ``demo.checks`` list; ``inputs`` are the demo's answers that ``${name}`` may name.

    Raises:
        DataFileError: (of ``f``'s kind) ``file:line: key: problem`` for the first wrong item.
    """
    return tuple(_check(item, inputs) for item in f.sequence())


def _check(f: Field, inputs: dict[str, str]) -> WorldCheck:
    f.mapping(any_keys=True)
    named = [key for key in SUBJECTS if f.has(key)]
    if len(named) != 1:
        raise f.fail(
            f"a check names one of {', '.join(SUBJECTS)} (what is checked), got {', '.join(named) if named else 'none'}"
        )
    kind = named[0]
    if kind == "topic":
        f.mapping(required=("topic", "equals"))
        return TelemetryCheck(f["topic"].text(), _expected(f["equals"], inputs))
    if kind == "images_of":
        f.mapping(required=("images_of",))
        return ImagesCheck(_targets(f["images_of"]))
    f.mapping(required=(kind, "within_mm"), optional=("at", "visits", "within_deg"))
    when = [key for key in ("at", "visits") if f.has(key)]
    if len(when) != 1:
        raise f.fail(f"say where the {kind} should be: 'at' (at the end of the run) or 'visits' (at some moment of it)")
    return FrameCheck(
        subject=f[kind].text(),
        place=_place(f[when[0]]),
        within_mm=f["within_mm"].number(min=0.001),
        within_deg=f["within_deg"].number(min=0.001, max=180.0) if f.has("within_deg") else None,
        during_run=when[0] == "visits",
    )


def _place(f: Field) -> Place:
    if f.node.kind == "scalar":
        return Place(f.text())
    f.mapping(required=("xyz",), optional=("frame", "rpy"))
    return Place(
        frame=f["frame"].text() if f.has("frame") else "world",
        xyz=f["xyz"].numbers(3),
        rpy=f["rpy"].numbers(3) if f.has("rpy") else (0.0, 0.0, 0.0),
        named=False,
    )


def _expected(f: Field, inputs: dict[str, str]) -> str | bool | int | float:
    value = f.node.value if f.node.kind == "scalar" else None
    if isinstance(value, (bool, int, float)):
        return f.number() if isinstance(value, float) else value
    text = f.text(empty=True)
    for name in _INPUT.findall(text):
        if name not in inputs:
            raise f.fail(
                f"${{{name}}} is not one of the demo's inputs ({', '.join(inputs) or 'it has none'}); "
                "add it to demo.inputs or write the value"
            )
    return _INPUT.sub(lambda m: inputs[m.group(1)], text)


def _targets(f: Field) -> tuple[str, ...] | None:
    if f.node.kind == "scalar":
        if f.text() != EVERY_TARGET:
            raise f.fail(f"expected {EVERY_TARGET!r} or a list of target names, got {f.text()!r}")
        return None
    return f.names(min_items=1)


def scene_frames(scene: Scene) -> list[str]:
    """The frames the simulation of ``scene`` publishes on ``sim/frames`` (docs/interfaces.md)."""
    frames = ["robot_base", scene.robot.tool_link]
    if "flange" in read_urdf(scene.robot.urdf).links:
        frames.append("flange")
    frames += [f"filter/{f.id}" for f in scene.filters]
    frames += list(scene.slots)
    frames += [f"target/{t.name}" for t in scene.targets]
    frames += [f"camera/{name}" for name in scene.cameras]
    return frames


def check_against_scene(f: Field, checks: tuple[WorldCheck, ...], scene: Scene) -> None:
    """Every frame and target ``checks`` name is one the simulation of ``scene`` has.

    Raises:
        DataFileError: at the line of the first one it does not have.
    """
    frames = scene_frames(scene)
    for item, check in zip(f.sequence(), checks, strict=True):
        if isinstance(check, FrameCheck):
            _check_subject(item, check, scene)
            field = item["visits" if check.during_run else "at"]
            if check.place.frame != "world" and check.place.frame not in frames:
                raise (field if check.place.named else field["frame"]).fail(
                    f"scene {scene.path.name} has no frame {check.place.frame!r}; its frames are "
                    f"world, {', '.join(frames)}"
                )
        elif isinstance(check, ImagesCheck):
            names = [t.name for t in scene.targets]
            if not names:
                raise item["images_of"].fail(f"scene {scene.path.name} has no targets to image")
            for index, name in enumerate(check.targets or ()):
                if name not in names:
                    raise (
                        item["images_of"]
                        .sequence()[index]
                        .fail(f"scene {scene.path.name} has no target {name!r}; its targets are {', '.join(names)}")
                    )


def _check_subject(item: Field, check: FrameCheck, scene: Scene) -> None:
    if item.has("tool"):
        if check.subject != scene.robot.tool_link:
            raise item["tool"].fail(
                f"the tool of scene {scene.path.name} is {scene.robot.tool_link!r} (its robot.tool_link)"
            )
        return
    objects = [f"filter/{f.id}" for f in scene.filters]
    if check.subject not in objects:
        raise item["object"].fail(
            f"scene {scene.path.name} has no object {check.subject!r}; its objects are {', '.join(objects) or 'none'}"
        )


# --- measuring ----------------------------------------------------------------------------------


def _ros_name(namespace: str, name: str) -> str:
    """``name`` as ROS resolves it in ``namespace``: a relative name lives inside it."""
    return name if name.startswith("/") else f"{namespace}/{name}"


def _frames(message: Mapping[str, Any]) -> dict[str, np.ndarray]:
    return {
        name: from_xyz_quat([pose["position"][k] for k in "xyz"], [pose["orientation"][k] for k in "xyzw"])
        for name, pose in zip(message["names"], message["poses"], strict=False)
    }


#: A check's measurement of one sample, ordered so that the least is the best: (misses, mm, degrees).
Measured = tuple[bool, float, float]


def _measured(check: FrameCheck, frames: dict[str, np.ndarray]) -> Measured:
    mm, deg = check.errors(frames)
    return (not check.holds(mm, deg), mm, deg)


class _World:
    """The robot side as the checks read it: one rosbridge connection (the project's client, on an
    event loop of its own thread), and for each check of a moment of the run its best sample so
    far (a long run keeps no history)."""

    def __init__(self, bridge_url: str | Endpoint, namespace: str, visits: tuple[FrameCheck, ...]) -> None:
        self.namespace = namespace
        self.samples = 0
        self.visits = visits
        self._best: dict[FrameCheck, Measured] = {}
        self._lock = threading.Lock()
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="world-checks", daemon=True)
        self._thread.start()
        endpoint = bridge_url if isinstance(bridge_url, Endpoint) else Endpoint(bridge_url)
        self._client = RosbridgeClient(endpoint, name="caretaker-world-checks")

    def connect(self) -> None:
        """Connect within :data:`TOPIC_TIMEOUT` (LinkError if the bridge does not answer)."""

        async def connected() -> None:
            self._client.start()
            try:
                await asyncio.wait_for(self._client.ready.wait(), TOPIC_TIMEOUT)
            except TimeoutError:
                raise LinkError(self._client.endpoint.url, f"no answer within {TOPIC_TIMEOUT:g} s") from None

        self._run(connected())

    def _run(self, work: Coroutine[Any, Any, T]) -> T:
        return asyncio.run_coroutine_threadsafe(work, self._loop).result()

    def watch(self) -> None:
        """Measure every frames sample from now on, for the checks of a moment of the run."""
        watched = Subscription(self.frames_topic, "caretaker_sim_msgs/NamedPoses", self._keep)
        self._run(_on_loop(lambda: self._client.subscribe(watched)))

    @property
    def frames_topic(self) -> str:
        return _ros_name(self.namespace, "sim/frames")

    def _keep(self, message: Mapping[str, Any]) -> None:
        frames = _frames(message)
        with self._lock:
            self.samples += 1
            for check in self.visits:
                if {check.subject, check.place.frame} - {"world"} <= frames.keys():
                    measured = _measured(check, frames)
                    self._best[check] = min(self._best.get(check, measured), measured)

    def best(self, check: FrameCheck) -> Measured | None:
        """The best sample of ``check`` seen since the watch began (None: none had its frames)."""
        with self._lock:
            return self._best.get(check)

    def truth(self) -> dict[str, np.ndarray]:
        """Every frame where it really is, from the simulation's ``sim/check/frames``."""
        name = _ros_name(self.namespace, "sim/check/frames")
        deadline = time.monotonic() + TOPIC_TIMEOUT
        while True:
            try:
                timeout = max(deadline - time.monotonic(), 0.1)
                response = self._run(self._client.call(name, {}, timeout=timeout))
                return _frames(response["frames"])
            except LinkError as exc:
                # A robot side just up may not have found the simulation's service yet ("no server
                # answering"); the call only reads, so asking again until the deadline is safe.
                if time.monotonic() >= deadline:
                    raise LookupError(f"{name} did not answer: {exc}") from None
                time.sleep(ASK_AGAIN_S)

    def newest(self, topic: str) -> Mapping[str, Any]:
        """The newest message of a latched topic: a new subscription is sent it at once."""
        received: list[Mapping[str, Any]] = []
        arrived = threading.Event()

        def take(message: Mapping[str, Any]) -> None:
            if not arrived.is_set():
                received.append(message)
                arrived.set()

        subscription = Subscription(topic, "", take)  # the bridge knows the topic's type
        self._run(_on_loop(lambda: self._client.subscribe(subscription)))
        try:
            if not arrived.wait(TOPIC_TIMEOUT):
                raise LookupError(f"no message on {topic} within {TOPIC_TIMEOUT:g} s")
            return received[0]
        finally:
            self._run(self._client.unsubscribe(subscription))

    def stop(self) -> None:
        self._run(self._client.close())
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join()
        self._loop.close()


async def _on_loop(call: Callable[[], None]) -> None:
    """Run ``call`` on the client's loop (the client schedules its sends there)."""
    call()


class WorldWatch:
    """The checks of one run: watching from before the procedure starts, judged after it ends."""

    def __init__(self, checks: tuple[WorldCheck, ...], world: _World | str, scene: Scene) -> None:
        self.checks = checks
        self.world = world  # or why the robot side could not be watched
        self.scene = scene

    def judge(self, db_url: str, run_id: str) -> list[Verdict]:
        """One verdict per check, in the order the deployment lists them."""
        verdicts = []
        end: dict[str, np.ndarray] | None = None
        for check in self.checks:
            try:
                if isinstance(check, ImagesCheck):
                    verdicts.append(_images(check, self.scene, db_url, run_id))
                elif isinstance(self.world, str):
                    verdicts.append(Verdict(False, self.world))
                elif isinstance(check, TelemetryCheck):
                    verdicts.append(_telemetry(check, self.world))
                else:
                    if end is None:
                        end = self.world.truth()
                    verdicts.append(_frame(check, self.world, end))
            except LookupError as exc:
                verdicts.append(Verdict(False, str(exc)))
        return verdicts


@contextmanager
def watch_world(
    checks: tuple[WorldCheck, ...], bridge_url: str | Endpoint, namespace: str, scene: Scene
) -> Iterator[WorldWatch]:
    """Watch the robot side behind ``bridge_url`` (or a bridge that wants TLS trust and a login:
    its :class:`Endpoint`) for ``checks`` while the block runs the procedure."""
    world: _World | str = "nothing of the robot side is read"
    if any(not isinstance(c, ImagesCheck) for c in checks):
        watching = _World(bridge_url, namespace, tuple(c for c in checks if isinstance(c, FrameCheck) and c.during_run))
        try:
            watching.connect()
        except LinkError as exc:
            watching.stop()
            world = f"cannot watch the robot side through {getattr(bridge_url, 'url', bridge_url)}: {exc}"
        else:
            world = watching
            if world.visits:
                world.watch()
    try:
        yield WorldWatch(checks, world, scene)
    finally:
        if isinstance(world, _World):
            world.stop()


def _frame(check: FrameCheck, world: _World, end: dict[str, np.ndarray]) -> Verdict:
    missing = [name for name in (check.subject, check.place.frame) if name != "world" and name not in end]
    if missing:
        raise LookupError(f"{world.frames_topic} has no frame {missing[0]!r}")
    at_end = _measured(check, end)
    if not check.during_run:
        misses, mm, deg = at_end
        where = f"{'is not' if misses else 'is'} at {check.place.words()}"
        return Verdict(not misses, f"{check.subject} {where}: {check.measure(mm, deg)}")
    seen = world.best(check)
    misses, mm, deg = min(seen, at_end) if seen else at_end  # the end is a sample of the run too
    if not misses:
        return Verdict(True, f"{check.subject} reached {check.place.words()}: {check.measure(mm, deg)}")
    return Verdict(
        False,
        f"{check.subject} never reached {check.place.words()} in {world.samples + 1} samples of the run; "
        f"nearest: {check.measure(mm, deg)}",
    )


def _telemetry(check: TelemetryCheck, world: _World) -> Verdict:
    topic = _ros_name(world.namespace, check.topic)
    value = world.newest(topic).get("data")
    if check.matches(value):
        return Verdict(True, f"{topic} is {value!r}")
    return Verdict(False, f"{topic} is {value!r}, expected {check.expected!r}")


def _images(check: ImagesCheck, scene: Scene, db_url: str, run_id: str) -> Verdict:
    """From the run's audit log: each target's last successful capture, and its file on disk."""
    from pride.event_payloads import CommandResult
    from records.audit_log import AuditLog

    targets = list(check.targets) if check.targets is not None else [t.name for t in scene.targets]
    audit = AuditLog(db_url)
    try:
        events = audit.events(run_id)
    finally:
        audit.close()
    images: dict[str, Path] = {}
    for event in events:
        data = event.data
        if isinstance(data, CommandResult) and data.success:
            path, label = data.values.get("path"), data.args.get("label")
            if path and label:
                images[label] = Path(path)
    missing = [t for t in targets if t not in images]
    empty = [t for t in targets if t in images and (not images[t].is_file() or images[t].stat().st_size == 0)]
    if missing or empty:
        problems = [f"no image captured of {', '.join(missing)}"] if missing else []
        problems += [f"image files missing or empty for {', '.join(empty)}"] if empty else []
        return Verdict(False, "; ".join(problems))
    return Verdict(True, f"images of {', '.join(targets)} captured ({len(targets)} non-empty files)")
