"""The 3D view's feed of one live run: robot state over the binding's rosbridge link, as the
view's contract (``spatial/README.md``), pushed to each browser at a bounded rate.

What it asks the habitat for (names under the robot's namespace), sized for a 1.3 s link:

| what | how | rate |
|---|---|---|
| ``robot_description``, ``sim/visual_world`` | subscribe (latched: once per connection) | once |
| ``joint_states`` | subscribe, ``throttle_rate`` 100 ms, ``queue_length`` 1 | <= 10/s |
| ``sim/frames`` | subscribe, ``throttle_rate`` 200 ms, ``queue_length`` 1 | <= 5/s |
| ``affordance_template_server/status`` | subscribe, ``throttle_rate`` 500 ms, ``queue_length`` 1 | <= 2/s |
| ``get_template_status`` per template | on a change, an AT command of the run, a reconnect (below) | on change |
| ``get_plan`` | when ``plan_id`` or the execute status change | on change |
| ``camera/<name>/image`` (camera below) | subscribe, ``throttle_rate`` 2 s, ``queue_length`` 1 | <= 1/2 s |
| ``perception/last_result`` | subscribe (latched), ``queue_length`` 1 | once per locate (a few hundred bytes) |

Perception's result is latched: a feed subscribing gets the last locate of whatever asked it,
often the run before. The view shows only this run's results, so a result is taken once the run
has sent a locate of its own (:meth:`SpatialFeed.locate_sent`).

``get_template_status`` is asked when ``running_templates``, ``plan_id`` or the execute status
change, after an AT command of the run, and after a reconnect. The camera is the one
:func:`~console.spatial_camera.choose_camera` picks.

Each browser gets the scene document once it exists, then the latest update of each kind,
never more often than :data:`PUSH_INTERVAL_S` (an update not yet sent is replaced by a newer
one of its kind: a slow browser or link gets fewer, fresher updates, never a growing queue).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from console.camera_feed import MOTION_COMMAND
from console.spatial_camera import CameraImageError, choose_camera, png_from_image
from console.spatial_link import ViewLink
from console.spatial_updates import joints_update, located_update, objects_update, templates_update
from console.spatial_values import SpatialDataError
from console.spatial_world import plan_from_get_plan, world_document
from rosbridge_wire.client import LinkError, RosbridgeClient, Subscription

__all__ = ["AT_COMMANDS_THAT_MOVE_TEMPLATES", "LOCATE_COMMAND", "PUSH_INTERVAL_S", "SpatialFeed", "ViewWatcher"]

log = logging.getLogger(__name__)

PUSH_INTERVAL_S = 0.1
JOINTS_THROTTLE_MS = 100
FRAMES_THROTTLE_MS = 200
STATUS_THROTTLE_MS = 500
CAMERA_THROTTLE_MS = 2000

#: The AT SysRep's commands (sysrep/affordance_templates.yaml) after which the templates or the
#: plan have changed: the feed asks again when one of the run's ends.
AT_COMMANDS_THAT_MOVE_TEMPLATES = frozenset(
    {
        "add_affordance_template",
        "delete_affordance_template",
        "set_display_object_pose",
        "set_waypoint_pose",
        "plan_trajectory",
        MOTION_COMMAND[1],
    }
)

#: Perception's command (sysrep/perception.yaml) whose results the view proposes registrations from.
LOCATE_COMMAND = ("perception", "locate")

Json = dict[str, Any]

#: What the view asks the AT server for, in the words an operator reads when it cannot be had
#: (the service's ROS name goes to the log: an operator meets commands, never services).
ASKED = {"get_template_status": "the templates' status", "get_plan": "the current plan"}


@dataclass(eq=False)  # each is one browser: hashed by identity
class ViewWatcher:
    """One browser's 3D view: what it still has to be sent, and a flag to wake its sender."""

    changed: asyncio.Event = field(default_factory=asyncio.Event)
    document: Json | None = None
    pending: dict[str, Json] = field(default_factory=dict)

    def take(self) -> tuple[Json | None, list[Json]]:
        document, updates = self.document, list(self.pending.values())
        self.document, self.pending = None, {}
        self.changed.clear()
        return document, updates


class SpatialFeed:
    """The habitat's state for one run's 3D views, kept current over one rosbridge link."""

    def __init__(self, link: ViewLink, *, camera_url: str, camera: str | None = None) -> None:
        """``camera_url``: where the page fetches :attr:`camera_png` (``?seq=N`` is added);
        ``camera``: the camera to show when the scene has it."""
        self.link = link
        self.camera_url = camera_url
        self.preferred_camera = camera
        self.camera: str | None = None
        self.camera_png: bytes | None = None
        self.camera_seq = 0
        self._camera_shown: tuple[Any, ...] | None = None  # the image message's pixels, as last shown
        self.rosbridge = RosbridgeClient(
            link.endpoint, name="pride-web-view", on_connected=self._refresh_all, on_state=self._link_state
        )
        self.watchers: set[ViewWatcher] = set()
        self.urdf: str | None = None
        self.visual_world: Mapping[str, Any] | None = None
        self.joints: Mapping[str, Any] | None = None
        self.frames: Mapping[str, Any] | None = None
        self.frame_poses: dict[str, Json] = {}
        self.templates: Json = {"kind": "templates", "templates": []}
        self.plan: Json = {"kind": "plan", "plan": None}
        # (template instance, display object) -> the frame the run last registered it to: the AT
        # server reports poses only, and a drag or a proposal is relative to that frame
        self.registrations: dict[tuple[str, str], str] = {}
        self.located_msg: Mapping[str, Any] | None = None  # perception's last result, as it came
        self.located: Json | None = None  # ... as the update made of it
        self.locating = False  # the run has sent a locate: results from before it were another run's
        self.status_key: tuple[Any, ...] | None = None
        self.plan_key: tuple[Any, ...] | None = None
        self.active_template = ""
        self.commanded: tuple[str, str] | None = None  # (instance, trajectory) the run sent a motion for
        self.last_error: str | None = None
        self._refreshing: asyncio.Task[None] | None = None
        self._refresh_again = False

    # ---- life -------------------------------------------------------------------------------
    def start(self) -> None:
        name = self.link.name
        self.rosbridge.subscribe(
            Subscription(name("robot_description"), "std_msgs/msg/String", self._on_urdf, queue_length=1)
        )
        self.rosbridge.subscribe(
            Subscription(name("sim/visual_world"), "caretaker_sim_msgs/msg/VisualWorld", self._on_world, queue_length=1)
        )
        self.rosbridge.subscribe(
            Subscription(
                name("joint_states"), "sensor_msgs/msg/JointState", self._on_joints, throttle_ms=JOINTS_THROTTLE_MS
            )
        )
        self.rosbridge.subscribe(
            Subscription(
                name("sim/frames"), "caretaker_sim_msgs/msg/NamedPoses", self._on_frames, throttle_ms=FRAMES_THROTTLE_MS
            )
        )
        self.rosbridge.subscribe(
            Subscription(
                name("affordance_template_server/status"),
                "affordance_template_msgs/msg/ServerStatus",
                self._on_status,
                throttle_ms=STATUS_THROTTLE_MS,
            )
        )
        self.rosbridge.subscribe(
            Subscription(
                name("perception/last_result"),
                "caretaker_perception_msgs/msg/LocateResult",
                self._on_located,
                queue_length=1,
            )
        )
        self.rosbridge.start()

    async def close(self) -> None:
        if self._refreshing is not None:
            self._refreshing.cancel()
        await self.rosbridge.close()

    def watch(self) -> ViewWatcher:
        watcher = ViewWatcher()
        watcher.document = self.document()
        if self.located is not None:  # after the document: it proposes the templates the document has
            watcher.pending["located"] = self.located
        watcher.changed.set()
        self.watchers.add(watcher)
        return watcher

    def unwatch(self, watcher: ViewWatcher) -> None:
        self.watchers.discard(watcher)

    def document(self) -> Json | None:
        """The whole scene now, or None until the latched URDF and visual world have arrived."""
        if self.urdf is None or self.visual_world is None:
            return None
        try:
            doc = world_document(
                self.visual_world, self.urdf, frames=self.frames, joints=self.joints, camera_url=self._camera_url()
            )
        except SpatialDataError as exc:
            self._report(f"the habitat's scene cannot be shown: {exc}")
            return None
        doc["templates"] = self.templates["templates"]
        doc["plan"] = self.plan["plan"]
        return doc

    # ---- pushing ----------------------------------------------------------------------------
    def _push(self, update: Json) -> None:
        for watcher in self.watchers:
            watcher.pending[str(update["kind"])] = update
            watcher.changed.set()

    def _push_document(self) -> None:
        doc = self.document()
        if doc is None:
            return
        for watcher in self.watchers:
            watcher.document, watcher.pending = doc, {}
            if self.located is not None:
                watcher.pending["located"] = self.located
            watcher.changed.set()

    def _report(self, message: str) -> None:
        if message != self.last_error:
            log.warning("3D view feed (%s): %s", self.link.endpoint.url, message)
        self.last_error = message
        self._push({"kind": "link", "state": "error", "message": message})

    def _link_state(self, state: str) -> None:
        self._push({"kind": "link", "state": state, "message": ""})

    # ---- topics -----------------------------------------------------------------------------
    def _on_urdf(self, msg: Mapping[str, Any]) -> None:
        self.urdf = str(msg.get("data", ""))
        self._push_document()

    def _on_world(self, msg: Mapping[str, Any]) -> None:
        self.visual_world = msg
        self._push_document()

    def _on_joints(self, msg: Mapping[str, Any]) -> None:
        try:
            update = joints_update(msg)
        except SpatialDataError as exc:
            self._report(str(exc))
            return
        self.joints = msg
        self._push(update)

    def _on_frames(self, msg: Mapping[str, Any]) -> None:
        try:
            update = objects_update(msg)
        except SpatialDataError as exc:
            self._report(str(exc))
            return
        self.frames, self.frame_poses = msg, update["poses"]
        self._push(update)
        if self.located_msg is not None and self.located is None:
            self._show_located()
        if self.camera is None:
            self.camera = choose_camera(self.frame_poses, self.preferred_camera)
            if self.camera is not None:
                self.rosbridge.subscribe(
                    Subscription(
                        self.link.name(f"camera/{self.camera}/image"),
                        "sensor_msgs/msg/Image",
                        self._on_image,
                        throttle_ms=CAMERA_THROTTLE_MS,
                    )
                )

    def locate_sent(self) -> None:
        """The run sent a locate (or had sent one when this feed was made): its results are this run's."""
        self.locating = True

    def _on_located(self, msg: Mapping[str, Any]) -> None:
        """The habitat's last locate: pushed as a proposal, kept for a view that opens later; one
        that came before the run located anything is another run's, latched, and is not shown.
        Its pose may be in a named frame: until ``sim/frames`` has come, it waits for them."""
        if not self.locating:
            return
        self.located_msg, self.located = msg, None
        if self.frame_poses:
            self._show_located()

    def _show_located(self) -> None:
        try:
            self.located = located_update(self.located_msg or {}, self.frame_poses)
        except SpatialDataError as exc:
            self.located_msg = None
            self._report(f"perception's result cannot be shown: {exc}")
            return
        self._push(self.located)

    def _on_image(self, msg: Mapping[str, Any]) -> None:
        # An idle robot's camera sends the same pixels again: encoded and pushed only when they change
        shown = tuple(msg.get(key) for key in ("encoding", "width", "height", "step", "data"))
        if shown == self._camera_shown:
            return
        try:
            self.camera_png = png_from_image(msg)
        except CameraImageError as exc:
            self._report(f"camera {self.camera}: {exc}")
            return
        self.camera_seq += 1
        self._camera_shown = shown
        self._push({"kind": "camera", "url": self._camera_url()})

    def _camera_url(self) -> str | None:
        return f"{self.camera_url}?seq={self.camera_seq}" if self.camera_png is not None else None

    def _on_status(self, msg: Mapping[str, Any]) -> None:
        running = tuple(str(t) for t in msg.get("running_templates", []) or [])
        self.active_template = str(msg.get("active_template", ""))
        execute = str(msg.get("execute_status", ""))
        plan_key = (str(msg.get("plan_id", "")), execute, self.active_template)
        status_key = (running, *plan_key, str(msg.get("plan_status", "")))
        if status_key != self.status_key:
            self.status_key = status_key
            self.refresh(plan=plan_key != self.plan_key)
            self.plan_key = plan_key

    # ---- services, asked on change ----------------------------------------------------------
    def refresh(self, *, plan: bool = True) -> None:
        """Ask the templates (and the plan) again; one request at a time, the last one wins."""
        if self._refreshing is not None and not self._refreshing.done():
            self._refresh_again = True
            return
        self._refreshing = asyncio.get_running_loop().create_task(self._refresh(plan))

    async def _refresh_all(self) -> None:
        self.refresh(plan=True)

    async def _refresh(self, plan: bool) -> None:
        while True:
            self._refresh_again = False
            # Asked together: over a 1.3 s link each question is a round trip, and a plan asked
            # after the templates would come a round trip later still.
            asked = [self._ask_templates(), self._ask_plan()] if plan else [self._ask_templates()]
            for outcome in await asyncio.gather(*asked, return_exceptions=True):
                if isinstance(outcome, (LinkError, SpatialDataError)):
                    self._report(str(outcome))
                elif isinstance(outcome, Exception):  # never a traceback to the browser; logged whole here
                    log.error("3D view feed refresh failed", exc_info=outcome)
                    self._report(f"{type(outcome).__name__}: {outcome}")
                elif isinstance(outcome, BaseException):
                    raise outcome
            if not self._refresh_again:
                return
            plan = True

    async def _ask(self, service: str, request: Json) -> Mapping[str, Any]:
        """The AT server's answer to ``service``; a LinkError in the operator's words if none."""
        name = self.link.name(f"affordance_template_server/{service}")
        try:
            return await self.rosbridge.call(name, request)
        except LinkError as exc:
            log.warning("3D view feed: %s", exc)
            reason = str(exc).removeprefix(f"{exc.what}: ")
            if service in reason:  # rosbridge's own refusal names the service
                reason = "the robot side refused the request"
            raise LinkError(f"could not read {ASKED[service]} from the robot", reason) from None

    async def _ask_templates(self) -> None:
        running = self.status_key[0] if self.status_key else ()
        statuses = [await self._ask("get_template_status", {"name": key, "frame_id": "world"}) for key in running]
        self.templates = templates_update(
            [_status_entry(s, key) for s, key in zip(statuses, running, strict=True)],
            frames=self.frames,
            registrations=self.registrations,
        )
        self._push(self.templates)

    async def _ask_plan(self) -> None:
        # While a motion the run sent has no answer, its plan is the one shown: the habitat's
        # status naming the active template is a light time old.
        instance, trajectory = self.commanded or (self.active_template, "")
        if not instance:
            self.plan = {"kind": "plan", "plan": None}
        else:
            answer = await self._ask("get_plan", {"name": instance, "trajectory_name": trajectory})
            self.plan = plan_from_get_plan(answer, instance=instance, frames=self.frame_poses, sent=self.commanded)
        self._push_plan()

    # ---- the run's commands -----------------------------------------------------------------
    def registered(self, args: Mapping[str, Any]) -> None:
        """The run registered a display object (set_display_object_pose succeeded with ``args``):
        remember the frame, so the view shows it registered there (what a drag is relative to,
        and which display objects a located frame proposes)."""
        template, name, frame = (str(args.get(k, "")) for k in ("affordance_template", "display_object", "frame"))
        if ":" not in template:
            template = f"{template}:{args.get('id', '')}"
        if template and name:
            self.registrations[(template, name)] = frame or "world"

    def command_sent(self, instance: str, trajectory: str) -> None:
        """The run sent the motion command (``execute_plan``) for ``instance``'s ``trajectory``: its
        plan is drawn as the path the arm has been told to follow from now, not a light time later
        when the habitat reports it executing (on a 1.3 s link a short motion would otherwise end
        before its path came)."""
        self.commanded = (instance, trajectory)
        plan = self.plan["plan"]
        if plan is None or (plan["instance"], plan["trajectory"]) != self.commanded:
            # The plan is not here yet (its refresh is a round trip behind the run): ask now,
            # or a short motion is over on the habitat before its path is drawn.
            self.refresh()
        self._push_plan()

    def command_ended(self) -> None:
        """The run's motion command has its answer: the plan is what the habitat says again."""
        self.commanded = None
        self.refresh()

    def _push_plan(self) -> None:
        plan = self.plan["plan"]
        if plan is not None and not plan["commanded"] and (plan["instance"], plan["trajectory"]) == self.commanded:
            self.plan = {"kind": "plan", "plan": {**plan, "commanded": True}}
        self._push(self.plan)


def _status_entry(answer: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    """The status of the instance's current trajectory from a get_template_status answer
    (which lists one per trajectory)."""
    if not answer.get("success"):
        raise SpatialDataError(f"the status of {key}", str(answer.get("message") or "refused"))
    statuses = [s for s in answer.get("affordance_template_status", []) or [] if isinstance(s, Mapping)]
    current = str(answer.get("current_trajectory", ""))
    chosen = next((s for s in statuses if s.get("trajectory_name") == current), statuses[0] if statuses else None)
    if chosen is None:
        raise SpatialDataError(f"the status of {key}", "the answer lists no status")
    return chosen
