"""Issue 17 on the real stacks: the console's 3D view fed by the ground server over rosbridge.

``caretaker up iva`` (simulation, planner, AT server, rosbridge) and ``caretaker serve`` with the
JVM PAX plugins; Chromium with WebGL on SwiftShader. The habitat's own answers, read here with
roslibpy over the same bridge, are the truth the view is held to: the URDF's links, the
``cabinet/slot`` frame the filter AT is registered to, the AT server's waypoints and plan. A drag
is sent as the operator through the executive and is in the audit log with the user and the
pose; a re-plan uses it; an observer's drag is refused (no handles, and 403 when forced). The EVA
stack shows the EVA arm and the hull targets. The frame rate while the arm moves is printed
(``docs/benchmarks.md``), not asserted. Screenshots go to ``$CARETAKER_SCREENSHOTS`` only.
"""

from __future__ import annotations

import json
import os
import statistics
import time
import xml.etree.ElementTree as ElementTree
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import roslibpy
import yaml
from playwright.sync_api import Browser, Page, expect
from spatial_data import crosses, matrix, world_boxes
from spatial_names import names_hide_nothing

from at_ros.transforms import angle_between
from console.spatial_world import compose
from pride.events import EventKind
from records.audit_log import AuditLog
from support.browser import TIMEOUT_MS
from support.operator_page import IVA, audit_row, instruction, sign_in_on, start_run, stop_run, unlock_approved_by
from support.stack import stack_up
from support.web_server import REPO, WebServer, start_server

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=70), pytest.mark.timeout(900)]

MM = 1e-3
AT = "/affordance_template_server"
SHOTS = Path(os.environ["CARETAKER_SCREENSHOTS"]) if os.environ.get("CARETAKER_SCREENSHOTS") else None


class Habitat:
    """The stack's own answers over rosbridge (roslibpy), independent of the web server."""

    def __init__(self, url: str) -> None:
        host, port = url.split("//")[1].rsplit(":", 1)
        self.ros = roslibpy.Ros(host, int(port))
        self.ros.run(timeout=30)
        self.frames: dict[str, Any] = {}
        self.urdf = ""
        roslibpy.Topic(
            self.ros, "/sim/frames", "caretaker_sim_msgs/msg/NamedPoses", throttle_rate=100, queue_length=1
        ).subscribe(self._on_frames)
        roslibpy.Topic(self.ros, "/robot_description", "std_msgs/msg/String").subscribe(self._on_urdf)

    def _on_frames(self, msg: dict[str, Any]) -> None:
        self.frames = {
            n: {"xyz": [p["position"][k] for k in "xyz"], "quat": [p["orientation"][k] for k in "xyzw"]}
            for n, p in zip(msg["names"], msg["poses"], strict=True)
        }

    def _on_urdf(self, msg: dict[str, Any]) -> None:
        self.urdf = msg["data"]

    def links(self) -> set[str]:
        wait_until(lambda: bool(self.urdf), "robot_description")
        return {link.get("name", "") for link in ElementTree.fromstring(self.urdf).findall("link")}

    def frame(self, name: str) -> dict[str, Any]:
        wait_until(lambda: name in self.frames, f"{name} on sim/frames")
        return self.frames[name]

    def call(self, service: str, args: dict[str, Any], type_: str) -> dict[str, Any]:
        answer: dict[str, Any] = roslibpy.Service(self.ros, service, type_).call(
            roslibpy.ServiceRequest(args), timeout=120
        )
        return answer

    def plan(self, name: str) -> dict[str, Any]:
        return self.call(
            f"{AT}/get_plan", {"name": name, "trajectory_name": ""}, "affordance_template_msgs/srv/GetPlan"
        )

    def plan_end_in_world(self, plan: dict[str, Any]) -> np.ndarray:
        stamped = plan["end_pose"]
        p = stamped["pose"]
        local = {"xyz": [p["position"][k] for k in "xyz"], "quat": [p["orientation"][k] for k in "xyzw"]}
        frame = stamped["header"]["frame_id"]
        return matrix(local if frame == "world" else compose(self.frame(frame), local))

    def close(self) -> None:
        self.ros.close()


def wait_until(condition: Callable[[], bool], what: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.1)


def drawn_where_the_arm_is(page: Page, habitat: Habitat, where: str) -> None:
    """Wait until the view's drawn tool is within 5 mm of the habitat's tool0 (the arm at rest)."""
    wait_until(
        lambda: distance(inspect(page)["tool_pose"], matrix(habitat.frame("tool0")))[0] <= 5 * MM,
        f"the view's tool {where}",
        timeout=TIMEOUT_MS * 3 / 1000,
    )


def distance(a: dict[str, Any], b: np.ndarray) -> tuple[float, float]:
    m = matrix(a)
    return float(np.linalg.norm(m[:3, 3] - b[:3, 3])), float(angle_between(m, b))


def assert_pose(
    actual: dict[str, Any], expected: np.ndarray, what: str, *, position: float = MM, angle: float = 0.01
) -> None:
    d, a = distance(actual, expected)
    assert d <= position and a <= angle, f"{what}: {d * 1000:.2f} mm, {np.degrees(a):.2f} deg away"


def wait_for_pose(page: Page, name: str, expected: np.ndarray) -> None:
    """Wait until the view shows the template part ``name`` within a millimetre of ``expected``."""
    wait_until(
        lambda: distance(inspect(page)["templates"][name]["pose"], expected)[0] <= MM,
        f"{name} in the view at its pose",
        timeout=30,
    )


def inspect(page: Page) -> dict[str, Any]:
    return page.evaluate("window.caretakerSpatial.inspect()")


def wait_view(page: Page, condition: str) -> None:
    """Wait until ``condition`` (JS over ``v``, the view's inspect()) holds."""
    page.wait_for_function(
        "(() => { const s = window.caretakerSpatial; if (!s) return false; "
        f"const v = s.inspect(); return {condition}; }})()",
        timeout=TIMEOUT_MS * 3,
    )


def act(page: Page, action: str, **extra: Any) -> None:
    page.evaluate(
        "([a, e]) => api('POST', `/api/runs/${encodeURIComponent(view.runId)}/actions`, {action: a, ...e})",
        [action, extra],
    )


def expect_camera_image(page: Page) -> None:
    """The robot camera's image, inset in the view, loaded from the ground server."""
    page.wait_for_function(
        "(() => { const i = document.querySelector('#spatial-view img.ct-spatial-camera');"
        " return i && !i.hidden && i.complete && i.naturalWidth > 0; })()",
        timeout=TIMEOUT_MS,
    )


def shoot(page: Page, name: str) -> None:
    if SHOTS is not None:
        SHOTS.mkdir(parents=True, exist_ok=True)
        page.locator("#spatial-view").screenshot(path=str(SHOTS / name))


@pytest.fixture
def open_as(webgl_browser: Browser) -> Iterator[Callable[[WebServer, str], Page]]:
    contexts = []
    errors: list[str] = []

    def open_(server: WebServer, user: str) -> Page:
        context = webgl_browser.new_context(viewport={"width": 1500, "height": 1000})
        contexts.append(context)
        page = context.new_page()
        page.on("pageerror", lambda error: errors.append(f"{user}: {error}"))
        page.set_default_timeout(TIMEOUT_MS)
        page.goto(server.url)
        sign_in_on(page, user)
        return page

    yield open_
    for context in contexts:
        context.close()
    assert not errors, "the page raised script errors:\n" + "\n".join(errors)


def names_clear_at_both_widths_and_enlarged(page: Page) -> None:
    """Names on (the default), the filter's display object, the robot camera and the plan's
    controls in the panel: at 1500 px and at 1024 px half of the display object stays in sight and
    no name lies on another or on a control; then the view fills the window and Esc puts it back."""
    for width, height in ((1500, 1000), (1024, 768)):
        page.set_viewport_size({"width": width, "height": height})
        wait_view(page, "v.settled")
        found = names_hide_nothing(page, "cdra_filter:0", f"console at {width} px")
        print(
            f"3D view names at {width} px: {found['visible']:.0%} of the display object visible, "
            f"{found['placed']} names shown, {found['unplaced']} without room"
        )
    page.set_viewport_size({"width": 1500, "height": 1000})
    page.click("#spatial-view [data-action=enlarge]")
    wait_view(page, "v.enlarged && v.settled")
    box = page.locator("#spatial-view").bounding_box()
    assert box is not None and (box["width"], box["height"]) == (1500, 1000), box
    names_hide_nothing(page, "cdra_filter:0", "enlarged view")
    if SHOTS is not None:
        page.screenshot(path=str(SHOTS / "spatial-iva-enlarged.png"))
    page.keyboard.press("Escape")
    wait_view(page, "!v.enlarged && v.settled")
    box = page.locator("#spatial-view").bounding_box()
    assert box is not None and box["width"] < 1500, box


def test_iva_view_follows_the_robot_registers_by_drag_and_refuses_observers(
    open_as: Callable[[WebServer, str], Page], tmp_path: Path, ros_env: dict[str, str]
) -> None:
    with stack_up("iva", ros_env, time_scale="1") as stack:
        # IVA's camera, captured as often as caretaker serve does by default, as a console would
        server = start_server(
            tmp_path, REPO / "procedures", rosbridge=[stack.url], cameras=["scene"], options=["--camera-period", "0.5"]
        )
        habitat = Habitat(stack.url)
        try:
            run_iva(open_as, server, habitat)
        finally:
            habitat.close()
            server.process.stop()


def run_iva(open_as: Callable[[WebServer, str], Page], server: WebServer, habitat: Habitat) -> None:
    alice = open_as(server, "alice")
    run_id = start_run(alice, IVA, "manual")
    expect(alice.locator("#spatial-panel")).to_be_visible()
    wait_view(alice, "v.settled && Object.keys(v.links).length > 0")
    assert set(inspect(alice)["links"]) == habitat.links(), "the view's robot is the habitat's URDF"

    # PAX adds, registers and plans (steps 1 and 2.1-2.2) and holds before 2.3; the arm moves to its
    # ready pose, and the view's frame rate is measured while it does (again during the pull-out)
    frame_rate = FrameRate(alice)
    act(alice, "set_breakpoint", instruction="2.3")
    act(alice, "mode", mode="autonomous")
    frame_rate.measure_until("view.state.current === '2.3' && view.state.hold !== null && !view.state.executing")
    expect(instruction(alice, "2.2").locator(".mark")).to_contain_text("completed", timeout=TIMEOUT_MS * 3)

    slot = matrix(habitat.frame("cabinet/slot"))
    wait_view(alice, "v.templates['cdra_filter:0'] !== undefined")
    wait_for_pose(alice, "cdra_filter:0", slot)
    assert_pose(
        inspect(alice)["templates"]["cdra_filter:0"]["pose"],
        slot,
        "the filter display object at its registration (cabinet/slot)",
    )
    status = habitat.call(
        f"{AT}/get_template_status",
        {"name": "cdra_filter:0", "trajectory_name": "grasp_and_pull", "frame_id": "world"},
        "affordance_template_msgs/srv/GetAffordanceTemplateStatus",
    )
    expected_waypoints = {
        f"{w['id']}.{k}:cdra_filter:0"
        for s in status["affordance_template_status"]
        if s["trajectory_name"] == "grasp_and_pull"
        for w in s["waypoint_info"]
        for k in range(len(w["waypoint_poses"]))
    }
    assert expected_waypoints
    # each waypoint reaches the view in an update of its own: wait for them all, then check their kind
    wait_view(alice, f"{json.dumps(sorted(expected_waypoints))}.every(name => v.templates[name] !== undefined)")
    templates = inspect(alice)["templates"]
    shown = {name for name, t in templates.items() if t["kind"] == "waypoint" and t["template"] == "cdra_filter:0"}
    assert expected_waypoints <= shown, f"waypoints: habitat {sorted(expected_waypoints)}, view {sorted(shown)}"

    plan = habitat.plan("cdra_filter:0")
    assert plan["state"] == "PLANNED", plan["message"]
    wait_view(alice, "v.ghost.visible")
    assert_pose(
        inspect(alice)["ghost"]["tool_pose"],
        habitat.plan_end_in_world(plan),
        "the ghost's last pose is the plan's end pose",
    )
    expect_camera_image(alice)
    shoot(alice, "spatial-iva.png")
    if SHOTS is not None:
        alice.screenshot(path=str(SHOTS / "spatial-iva-console.png"))
    names_clear_at_both_widths_and_enlarged(alice)

    # the operator drags the filter's display object 5 cm towards the robot and releases
    moved = slot.copy()
    moved[1, 3] -= 0.05
    alice.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0', {translate: [0, -0.05, 0]})")
    expect(alice.locator("#spatial-status")).to_contain_text("set_display_object_pose succeeded", timeout=TIMEOUT_MS)
    expect(alice.locator("#spatial-status")).to_have_text("", timeout=TIMEOUT_MS)  # news for a moment, not the run
    wait_for_pose(alice, "cdra_filter:0", moved)
    assert_pose(inspect(alice)["templates"]["cdra_filter:0"]["pose"], moved, "the display object where it was dropped")
    wait_view(alice, "!v.ghost.visible")  # the registration invalidated the plan: no ghost of it
    log = AuditLog(server.database.url)
    try:
        sent = [
            e
            for e in log.events(run_id)
            if e.kind is EventKind.COMMAND_SENT
            and e.data.to_json().get("command") == "set_display_object_pose"
            and e.actor == "alice"
            and e.instruction is None
        ]
        results = [
            e
            for e in log.events(run_id)
            if e.kind is EventKind.COMMAND_RESULT and e.data.to_json().get("key") == sent[-1].data.to_json()["key"]
        ]
    finally:
        log.close()
    assert len(sent) == 1, "one drag, one command in the audit log, by alice"
    args = sent[0].data.to_json()["args"]
    assert args["display_object"] == "cdra_filter" and args["affordance_template"] == "cdra_filter"
    dropped = compose(
        habitat.frame(args["frame"]) if args["frame"] != "world" else {"xyz": [0, 0, 0], "quat": [0, 0, 0, 1]},
        {"xyz": [args["x"], args["y"], args["z"]], "quat": rpy_quat(args["roll"], args["pitch"], args["yaw"])},
    )
    assert_pose(dropped, moved, "the logged pose is where it was dropped")
    assert results and results[0].data.to_json()["success"] is True and results[0].actor == "alice"

    # A re-plan uses the new registration: the drag said where the filter is, and the planner's
    # world follows it (the cabinet with its slot and filter: at_ros/registered_world.py), so the
    # grasp plans 5 cm off, its end moved with the registration. Dragged back to 1 cm off, again.
    def replan() -> dict[str, Any]:
        answer = habitat.call(
            f"{AT}/plan_command",
            {"type": "cdra_filter", "id": 0, "trajectory_name": "grasp_and_pull"},
            "affordance_template_msgs/srv/AffordanceTemplatePlanCommand",
        )
        assert answer["success"], answer["message"]
        return habitat.plan("cdra_filter:0")

    old_end = habitat.plan_end_in_world(plan)
    near = slot.copy()
    near[1, 3] -= 0.01
    for offset, dragged_to, drag in ((0.05, moved, None), (0.01, near, [0, 0.04, 0])):
        if drag is not None:
            alice.evaluate(f"window.caretakerSpatial.dragBy('cdra_filter:0', {{translate: {drag}}})")
            wait_for_pose(alice, "cdra_filter:0", dragged_to)
            assert_pose(inspect(alice)["templates"]["cdra_filter:0"]["pose"], dragged_to, "dragged back")
        new_plan = replan()
        assert new_plan["plan_id"] != plan["plan_id"]
        shift = habitat.plan_end_in_world(new_plan)[:3, 3] - old_end[:3, 3]
        assert shift == pytest.approx([0, -offset, 0], abs=2 * MM), f"the re-plan's end moved by {shift}"
    wait_view(alice, "v.ghost.visible")
    assert_pose(inspect(alice)["ghost"]["tool_pose"], habitat.plan_end_in_world(new_plan), "the ghost of the re-plan")

    # an observer sees the same and can move nothing
    carol = open_as(server, "carol")
    carol.goto(f"{server.url}/#run={run_id}")
    wait_view(carol, "v.templates['cdra_filter:0'] !== undefined && v.ghost.visible")
    refused = carol.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0', {translate: [0, 0.05, 0]})")
    assert refused.get("refused"), refused
    token = {"X-CSRF-Token": carol.evaluate("view.me.csrf")}
    forced = carol.request.post(
        f"{server.url}/api/runs/{run_id}/spatial/pose",
        headers=token,
        data={"command": "set_display_object_pose", "args": args},
    )
    assert forced.status == 403 and "observer" in forced.json()["error"], forced.text()
    expect(audit_row(alice, "action_refused", "", "carol")).to_contain_text("refused move by the observers watch rule")
    # a console of its own machine: two 3D views on these two cores would halve the frame rate measured below
    carol.close()

    # Execute: PAX runs on, past the unlock a second operator approves, to the operator's manual
    # check (2.6); once she marks it done, PAX executes the pull-out (2.7), the ghost goes (the live
    # arm shows what happens) and stays gone after
    act(alice, "set_breakpoint", instruction="2.8")
    act(alice, "continue")
    unlock_approved_by(alice, "bob", timeout=TIMEOUT_MS)  # hazardous in the cdra SysRep: bob approves it
    wait_until_state(alice, "view.state.current === '2.6' && view.state.hold === 'operator_action'")
    assert inspect(alice)["ghost"]["visible"], "the ghost of the plan about to run"
    # looked at from above the cabinet, near the wall: its housing is between the eye and the
    # gripper while the gripper works at the slot. The view draws the arm from what comes down
    # from the habitat, on a loaded machine seconds behind the run's state: the reads go on until
    # the drawn tool is where the pull-out ended, and the last is taken there, at rest
    alice.evaluate(f"window.caretakerSpatial.look({ABOVE_EYE}, {CABINET_SLOT})")
    sight = GripperInSight(alice)
    act(alice, "done", instruction="2.6")
    wait_view(alice, "!v.ghost.visible")
    frame_rate.measure_until("view.state.current === '2.8' && view.state.hold !== null && !view.state.executing")
    drawn_where_the_arm_is(alice, habitat, "where the arm stopped after the pull-out")
    frame_rate.report()
    sight.check(at_rest_from=OVER_CABINET_EYE)
    expect(instruction(alice, "2.7").locator(".mark")).to_contain_text("completed", timeout=TIMEOUT_MS)
    assert habitat.plan("cdra_filter:0")["state"] != "PLANNED"
    assert not inspect(alice)["ghost"]["visible"], "no ghost of a plan that ran"

    # moving a waypoint sends set_waypoint_pose, and the habitat's waypoint follows
    waypoint = "0.0:cdra_filter:0"
    before = matrix(inspect(alice)["templates"][waypoint]["pose"])
    target = before.copy()
    target[2, 3] += 0.01
    alice.evaluate(f"window.caretakerSpatial.dragBy('{waypoint}', {{translate: [0, 0, 0.01]}})")
    expect(alice.locator("#spatial-status")).to_contain_text("set_waypoint_pose succeeded", timeout=TIMEOUT_MS)
    wait_for_pose(alice, waypoint, target)
    assert_pose(inspect(alice)["templates"][waypoint]["pose"], target, "the waypoint where it was dropped")
    stop_run(alice, "3D view test done")


#: The cabinet's slot (sim/scenes/iva.yaml) and an eye above the cabinet, near the wall it hangs on.
CABINET_SLOT = [0.15, 0.90, 1.05]
ABOVE_EYE = [0.15, 1.00, 1.90]
#: Just over the cabinet's top, by the wall: its housing is between this eye and the filter held out.
OVER_CABINET_EYE = [0.15, 1.00, 1.45]


class GripperInSight:
    """Whether the scene objects between the view's eye and the gripper were faded while the arm
    worked inside the cabinet (the pull-out). What is between is worked out here from the scene
    file's boxes (sim/scenes/iva.yaml, as world-aligned boxes like the view's own), independently
    of the view; the page reads the eye, the drawn tool and the names the view faded every 50 ms
    during the motion (a starved page reads little: its timers wait on its frames), and once at
    rest, looked at from where an object is between (what makes the check certain to see one)."""

    START = """() => {
      window.sightRead = () => {
        const v = window.caretakerSpatial.inspect();
        window.sightReads.push([v.camera.eye, v.tool_pose.xyz, v.camera.faded]);
      };
      window.sightReads = [];
      window.sightTimer = setInterval(window.sightRead, 50);
    }"""
    #: Stop the timer, look at the drawn tool from ``eye``, read once more: all the reads.
    AT_REST = """(eye) => {
      clearInterval(window.sightTimer);
      const view = window.caretakerSpatial;
      view.look(eye, view.inspect().tool_pose.xyz);
      window.sightRead();
      return window.sightReads;
    }"""
    #: The view re-checks what hides the tool each time the drawn tool moved 2 cm: a box counts
    #: as in the way when the line of sight crosses it shrunk by this much.
    MARGIN_M = 0.03

    def __init__(self, page: Page) -> None:
        self.page = page
        scene = yaml.safe_load((REPO / "sim" / "scenes" / "iva.yaml").read_text())
        self.boxes = [(body["name"], box) for body in scene["bodies"] for box in world_boxes(body)]
        page.evaluate(self.START)

    def check(self, *, at_rest_from: list[float]) -> None:
        """Every read's objects between the eye and the gripper were faded; the last read (at rest,
        from ``at_rest_from``) must have had one between, or the check saw nothing to fade."""
        reads = self.page.evaluate(self.AT_REST, at_rest_from)
        self.reads = [(np.array(eye), np.array(tool), faded) for eye, tool, faded in reads]
        hidden = 0
        for eye, tool, faded in self.reads:
            between = self.between(eye, tool)
            if between:
                hidden += 1
                assert between <= set(faded), f"the gripper at {tool.round(3)} is behind {between}, faded: {faded}"
        print(f"gripper in sight: {hidden} of {len(self.reads)} reads had scene objects between it and the eye")
        eye, tool, faded = self.reads[-1]
        assert self.between(eye, tool), (
            f"at rest, looked at from {eye.round(2)}, no scene object is between the eye and the gripper at "
            f"{tool.round(3)} (faded {faded}): the check saw nothing to fade"
        )

    def between(self, eye: np.ndarray, tool: np.ndarray) -> set[str]:
        """The scene objects the line of sight from ``eye`` to the gripper crosses (not one it is in)."""
        return {
            name
            for name, (low, high) in self.boxes
            if crosses((low + self.MARGIN_M, high - self.MARGIN_M), eye, tool)
            and not np.all((low <= tool) & (tool <= high))
        }


class FrameRate:
    """Frames/s of the console's 3D view while the arm moves, for docs/benchmarks.md (printed, not
    asserted). The view is read every 0.25 s. Within one motion, the frames it drew between reads
    over the time between them, the motion's last stretch left out (the arm stops somewhere in it:
    the view counts a motion on for 0.3 s after its last joint state). Reported per motion and
    per quarter-second window (the smallest, noisy by one frame in six)."""

    PROBE = (
        "(() => { const v = window.caretakerSpatial.inspect();"
        " return [performance.now(), v.frames, v.arm_moving_ms, v.update_latency_ms, v.resolution_scale]; })()"
    )

    def __init__(self, page: Page) -> None:
        self.page = page
        self.motions: list[tuple[int, float]] = []  # frames, seconds
        self.windows: list[tuple[float, float, float]] = []  # frames/s, update-to-frame ms, resolution scale

    def measure_until(self, condition: str, timeout: float = 300.0) -> None:
        """Read the view until the run view satisfies ``condition`` (JS over ``view``)."""
        deadline = time.monotonic() + timeout
        motion: list[list[float]] = []  # the reads of the current motion
        while not self.page.evaluate(f"!!(view.state && ({condition}))"):
            assert time.monotonic() < deadline, f"the run did not reach {condition} in {timeout:.0f} s"
            probe = self.page.evaluate(self.PROBE)
            if motion and probe[2] - motion[-1][2] < 0.9 * (
                probe[0] - motion[-1][0]
            ):  # not moving all the time since the last read
                self._count(motion[:-1])
                motion = []
            if probe[2] > 0:
                motion.append(probe)
            self.page.wait_for_timeout(250)
        self._count(motion[:-1])

    def _count(self, motion: list[list[float]]) -> None:
        if len(motion) < 2:
            return
        self.motions.append((int(motion[-1][1] - motion[0][1]), (motion[-1][0] - motion[0][0]) / 1000))
        for (t0, frames0, _, _, _), (t1, frames1, _, latency, scale) in zip(motion, motion[1:], strict=False):
            if latency is not None:
                self.windows.append(((frames1 - frames0) * 1000 / (t1 - t0), latency, scale))

    def report(self) -> None:
        print(
            "\n3D view in the console (headless Chromium, SwiftShader, 1500x1000), "
            f"load average {os.getloadavg()[0]:.1f}; "
            "arm moving, joint states at 10/s, interpolated:"
        )
        if not self.motions:
            print("  no reading: the arm never moved for 0.5 s on end")
            return
        frames, seconds = sum(m[0] for m in self.motions), sum(m[1] for m in self.motions)
        per_motion = ", ".join(f"{f / t:.0f}" for f, t in self.motions)
        print(
            f"  {frames / seconds:.1f} frames/s over {len(self.motions)} motions ({seconds:.1f} s; each: {per_motion})"
        )
        if self.windows:
            fps, latency, scale = zip(*self.windows, strict=True)
            print(
                f"  quarter-second windows: median {statistics.median(fps):.0f}, min {min(fps):.0f} frames/s; "
                f"update-to-frame median {statistics.median(latency):.0f} ms; "
                f"resolution scale median {statistics.median(scale):.2f}; {len(fps)} windows"
            )


def wait_until_state(page: Page, condition: str) -> None:
    """Wait until the page's run view satisfies ``condition`` (a JS expression over ``view``)."""
    page.wait_for_function(f"view.state && ({condition})", timeout=TIMEOUT_MS)


def rpy_quat(roll: float, pitch: float, yaw: float) -> list[float]:
    from console.spatial_values import pose

    return list(pose(rpy=(roll, pitch, yaw))["quat"])


def test_eva_view_shows_the_eva_arm_and_the_hull_targets(
    open_as: Callable[[WebServer, str], Page], tmp_path: Path, ros_env: dict[str, str]
) -> None:
    with stack_up("eva", ros_env) as stack:
        server = start_server(tmp_path, REPO / "procedures", rosbridge=[stack.url])
        habitat = Habitat(stack.url)
        try:
            page = open_as(server, "alice")
            start_run(page, "eva_inspection.xml", "manual", binding="eva.yaml")
            wait_view(page, "v.settled && Object.keys(v.links).length > 0 && Object.keys(v.objects).length > 0")
            view = inspect(page)
            assert set(view["links"]) == habitat.links(), "the view's robot is the EVA arm's URDF"
            targets = {name for name, o in view["objects"].items() if o["kind"] == "target"}
            hull = {name for name in habitat.frames if name.startswith("target/")}
            assert hull and targets == hull, f"hull targets: habitat {sorted(hull)}, view {sorted(targets)}"
            for name in hull:
                assert_pose(view["objects"][name]["pose"], matrix(habitat.frame(name)), name, position=5 * MM)
            expect_camera_image(page)
            shoot(page, "spatial-eva.png")
            # at 1024 px the view stays beside the procedure, in view, and nothing overflows sideways
            page.set_viewport_size({"width": 1024, "height": 768})
            wait_view(page, "v.settled")
            box = page.locator("#spatial-view").bounding_box()
            procedure = page.locator("#procedure").bounding_box()
            assert box is not None and procedure is not None and box["width"] > 300, box
            assert box["x"] >= procedure["x"] + procedure["width"] and box["y"] + box["height"] <= 768, (box, procedure)
            assert page.evaluate("document.documentElement.scrollWidth") <= 1024
            if SHOTS is not None:
                page.screenshot(path=str(SHOTS / "spatial-eva-console-1024.png"))
            stop_run(page, "3D view test done")
        finally:
            habitat.close()
            server.process.stop()


#: A displaced Gateway (issue 28): its hull targets are where this seed put them, not where the
#: drawings (and so the frames the ground is told) have them.
DISPLACE_SEED = 17
#: The first target's registration with the values its locate (2.1/1.6) returned.
REGISTER_LOCATED = "2.1/1.7"


def test_a_located_target_is_a_proposal_the_operator_corrects_or_accepts(
    open_as: Callable[[WebServer, str], Page], tmp_path: Path, ros_env: dict[str, str]
) -> None:
    """Manual mode: PAX runs the EVA inspection to the first target's registration from the
    camera and holds there. The view draws the inspection template's display object where the
    camera found hull_a, beside where it is registered (hull_a's frame from the drawings); alice
    drags that proposal 1 cm to correct it (registered as hers), then perception locates hull_a
    again and she accepts the new proposal with the view's Accept (registered as hers too).
    Nothing is registered by the view without her."""
    with stack_up("eva", ros_env, displace=DISPLACE_SEED) as stack:
        server = start_server(tmp_path, REPO / "procedures", rosbridge=[stack.url])
        habitat = Habitat(stack.url)
        try:
            alice = open_as(server, "alice")
            run_id = start_run(alice, "eva_inspection.xml", "manual", binding="eva.yaml")
            act(alice, "set_breakpoint", instruction=REGISTER_LOCATED)
            act(alice, "mode", mode="autonomous")
            wait_until_state(alice, f"view.state.current === '{REGISTER_LOCATED}' && view.state.hold !== null")
            wait_view(alice, "Object.keys(v.registration.proposals).length === 1")
            view = inspect(alice)
            ((shown, proposal),) = view["registration"]["proposals"].items()
            located = view["registration"]["located"]
            assert located["object"] == "target/hull_a" and located["success"], located
            expect(alice.locator("#spatial-view [data-action='accept-proposal']")).to_be_visible()
            expect(alice.locator("#spatial-view .ct-spatial-status")).to_contain_text(
                "target/hull_a located by ee_camera"
            )

            # the proposal is the located pose the run's own locate returned, in the world; the
            # display object itself stays registered to the drawings' frame until alice acts
            values = _locate_values(server, run_id)
            nominal = habitat.frame("target/hull_a")
            rpy = (values["roll"], values["pitch"], values["yaw"])
            where_located = matrix(compose(nominal, {"xyz": [values[k] for k in "xyz"], "quat": rpy_quat(*rpy)}))
            assert_pose(proposal["pose"], where_located, "the proposal at the located pose", position=MM)
            assert_pose(view["templates"][shown]["pose"], matrix(nominal), "the display object still at the drawings")
            assert distance(proposal["pose"], matrix(nominal))[0] >= 5 * MM, "a displaced target is off the drawings"

            # a correction: the proposal dragged 1 cm up, registered where it was dropped, as alice's
            corrected = where_located.copy()
            corrected[2, 3] += 0.01
            alice.evaluate(
                f"window.caretakerSpatial.dragBy({shown!r}, {{translate: [0, 0, 0.01], fromProposal: true}})"
            )
            wait_for_pose(alice, shown, corrected)
            wait_view(alice, "Object.keys(v.registration.proposals).length === 0")  # acted on: proposed no more

            # perception locates hull_a again (the habitat's own service): a new proposal, accepted
            again = habitat.call(
                "/perception/locate",
                {"object": "target/hull_a", "camera": "ee_camera", "frame": "world", "tolerance_px": 0.0},
                "caretaker_perception_msgs/srv/Locate",
            )
            assert again["success"], again["message"]
            relocated = matrix({"xyz": [again[k] for k in "xyz"], "quat": [again[k] for k in ("qx", "qy", "qz", "qw")]})
            wait_view(alice, "Object.keys(v.registration.proposals).length === 1")
            alice.locator("#spatial-view [data-action='accept-proposal']").click()
            wait_for_pose(alice, shown, relocated)
            expect(alice.locator("#spatial-view [data-action='accept-proposal']")).to_be_hidden()

            registered = _registrations_by(server, run_id, "alice")
            assert len(registered) == 2, "one command for the correction, one for the acceptance, both alice's"
            for (args, success), expected in zip(registered, (corrected, relocated), strict=True):
                assert success is True and args["frame"] == "target/hull_a", args
                local = {"xyz": [args[k] for k in "xyz"], "quat": rpy_quat(args["roll"], args["pitch"], args["yaw"])}
                assert_pose(compose(nominal, local), expected, "the logged registration")
            stop_run(alice, "proposal checked")
        finally:
            habitat.close()
            server.process.stop()


def _locate_values(server: WebServer, run_id: str) -> dict[str, float]:
    """The values of the run's one successful perception.locate, from its audit log."""
    log = AuditLog(server.database.url)
    try:
        results = [
            e.data.to_json()
            for e in log.events(run_id)
            if e.kind is EventKind.COMMAND_RESULT
            and e.data.to_json().get("command") == "locate"
            and e.data.to_json().get("success")
        ]
    finally:
        log.close()
    assert len(results) == 1, results
    return {k: float(v) for k, v in results[0]["values"].items() if k in ("x", "y", "z", "roll", "pitch", "yaw")}


def _registrations_by(server: WebServer, run_id: str, user: str) -> list[tuple[dict[str, Any], bool]]:
    """(arguments, success) of each set_display_object_pose ``user`` sent outside the procedure."""
    log = AuditLog(server.database.url)
    try:
        events = log.events(run_id)
    finally:
        log.close()
    sent = [
        e
        for e in events
        if e.kind is EventKind.COMMAND_SENT
        and e.actor == user
        and e.instruction is None
        and e.data.to_json().get("command") == "set_display_object_pose"
    ]
    results = {e.data.to_json().get("key"): e for e in events if e.kind is EventKind.COMMAND_RESULT}
    return [
        (
            e.data.to_json()["args"],
            results[e.data.to_json()["key"]].data.to_json()["success"] if e.data.to_json()["key"] in results else None,
        )
        for e in sent
    ]
