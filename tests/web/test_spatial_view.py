"""The 3D view (``SpatialView``, python/console/spatial) in headless Chromium with WebGL.

Documents are made from the shipped scenes, URDFs and templates by the contract's producer
(``console.spatial_scene``) and the AT server's own status code (spatial_data.py); expected
poses come from pybullet and from ``at_ros``, never from the view. Screenshots go to
``$SPATIAL_SCREENSHOT_DIR`` or a temporary folder, never into the source tree.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Browser, Page
from spatial_data import REPO, Habitat, RunningTemplate, crosses, matrix
from spatial_names import READ_PIXELS, names_hide_nothing
from spatial_site import SpatialSite, serve_site

from at_ros.transforms import angle_between, from_xyz_rpy, invert, quat_from_matrix
from console.spatial_updates import objects_update
from support.browser import TIMEOUT_MS
from support.operator_page import shown_image_width

MM = 1e-3

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def site() -> Iterator[SpatialSite]:
    with serve_site() as served:
        yield served


@pytest.fixture(scope="module")
def iva() -> Iterator[Habitat]:
    habitat = Habitat.open("iva")
    yield habitat
    habitat.close()


@pytest.fixture(scope="module")
def eva() -> Iterator[Habitat]:
    habitat = Habitat.open("eva")
    yield habitat
    habitat.close()


@pytest.fixture(scope="module")
def screenshots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = Path(os.environ.get("SPATIAL_SCREENSHOT_DIR") or tmp_path_factory.mktemp("spatial-screenshots"))
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@pytest.fixture
def open_view(webgl_browser: Browser, site: SpatialSite) -> Iterator[Callable[..., Page]]:
    """``open_view(document, can_act=True, clock=False)``: a fresh page showing ``document``,
    rendering; with ``clock`` the page's timers and animation frames run on Playwright's clock."""
    contexts = []
    problems: list[str] = []

    def open_(document: dict[str, Any], *, can_act: bool = True, clock: bool = False) -> Page:
        context = webgl_browser.new_context(viewport={"width": 1000, "height": 700})
        contexts.append(context)
        page = context.new_page()
        if clock:  # the page's time is the test's: it runs only as the test advances it
            page.clock.install()
        page.set_default_timeout(TIMEOUT_MS)
        page.on("pageerror", lambda error: problems.append(f"page error: {error}"))
        page.on(
            "console", lambda msg: problems.append(f"console {msg.type}: {msg.text}") if msg.type == "error" else None
        )
        path = site.put_json(f"/documents/{len(site.files)}.json", document)
        page.goto(site.url + "/")
        page.evaluate("([url, canAct]) => window.startView(url, canAct)", [path, can_act])
        if clock:
            page.clock.run_for(1000)
        page.wait_for_function("window.caretakerSpatial && window.caretakerSpatial.inspect().settled")
        return page

    yield open_
    for context in contexts:
        context.close()
    assert not problems, "\n".join(problems)


def inspect(page: Page) -> dict[str, Any]:
    return page.evaluate("window.caretakerSpatial.inspect()")


def drawn(page: Page) -> None:
    """Wait until the view has drawn every change made so far (labels follow on render): a change
    marks the view to be drawn at once, so there is no frame to miss, as counting frames could."""
    page.wait_for_function("window.caretakerSpatial.inspect().settled")


def apply(page: Page, update: dict[str, Any]) -> None:
    assert page.evaluate("(u) => window.caretakerSpatial.apply(u)", update), page.evaluate("window.viewErrors")
    drawn(page)


def assert_pose(
    actual: dict[str, Any], expected: np.ndarray, what: str, *, position: float = MM, angle: float = 0.01
) -> None:
    m = matrix(actual)
    d = float(np.linalg.norm(m[:3, 3] - expected[:3, 3]))
    a = angle_between(m, expected)
    assert d <= position and a <= angle, f"{what}: {d * 1000:.2f} mm, {np.degrees(a):.2f} deg away from expected"


def assert_links(view_links: dict[str, Any], expected: dict[str, np.ndarray], what: str) -> None:
    assert set(view_links) == set(expected), f"{what}: links differ: view {sorted(view_links)}, URDF {sorted(expected)}"
    for name, pose in expected.items():
        assert_pose(view_links[name], pose, f"{what}: link {name}")


def iva_start(iva: Habitat) -> list[float]:
    return [float(v) for v in iva.mapping["robot"]["initial_positions"]]


# ------------------------------------------------------------------------------------ robot


def test_robot_links_follow_joint_updates(open_view: Callable[..., Page], iva: Habitat) -> None:
    document = iva.document()
    page = open_view(document)
    state = inspect(page)
    assert state["robot"] == "ur10" and state["frame"] == "world"
    assert_links(state["links"], iva.link_poses(document["joints"]["positions"]), "initial joints")

    # Only the last wrist joint moves: links before it stay, the ones after it turn.
    positions = dict(document["joints"]["positions"])
    positions["wrist_3_joint"] = 0.7
    before = state["links"]
    apply(page, {"kind": "joints", "stamp": 1.0, "positions": {"wrist_3_joint": 0.7}})
    after = inspect(page)["links"]
    expected = iva.link_poses(positions)
    assert_links(after, expected, "wrist_3_joint = 0.7")
    for name in ("base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link"):
        assert_pose(
            after[name], matrix(before[name]), f"{name} must not move with wrist_3_joint", position=1e-6, angle=1e-6
        )
    assert angle_between(matrix(after["wrist_3_link"]), matrix(before["wrist_3_link"])) == pytest.approx(0.7, abs=1e-3)

    # Every joint at once, gripper closed.
    rng = np.random.default_rng(3)
    arm = {n: float(v) for n, v in zip(iva.arm_joints, rng.uniform(-2.5, 2.5, len(iva.arm_joints)), strict=True)}
    update = {**arm, "gripper_left_finger_joint": 0.01, "gripper_right_finger_joint": 0.02}
    apply(page, {"kind": "joints", "stamp": 2.0, "positions": update})
    assert_links(inspect(page)["links"], iva.link_poses(update), "random joints")


#: Records what the view draws at every animation frame: [drawn, newest state sent].
WATCH_FRAMES = """(interpolate) => {
  const view = window.caretakerSpatial;
  view.setJointInterpolation(interpolate);
  window.watched = {start: view.robot.positions.wrist_3_joint, frames: []};
  window.newest = window.watched.start;
  const watch = () => {
    window.watched.frames.push([view.robot.positions.wrist_3_joint, window.newest]);
    requestAnimationFrame(watch);
  };
  requestAnimationFrame(watch);
}"""
SEND = """(value) => {
  window.newest = value;
  window.caretakerSpatial.apply({kind: 'joints', stamp: 0, positions: {wrist_3_joint: value}});
}"""


def _stream(page: Page, interpolate: bool, values: list[float]) -> dict[str, Any]:
    """Joint states of wrist_3 every 0.2 s of the page's clock, then 0.4 s with none; what was
    drawn at every animation frame meanwhile. The page's clock is Playwright's (timers and
    animation frames run as the test advances it), so a loaded machine cannot stretch the
    intervals into gaps that end the stream."""
    page.evaluate(WATCH_FRAMES, interpolate)
    for value in values:
        page.evaluate(SEND, value)
        page.clock.run_for(200)
    page.clock.run_for(400)
    watched: dict[str, Any] = page.evaluate("window.watched")
    page.evaluate("window.watched = {start: 0, frames: []}")  # the old watch keeps running into a dead list
    return watched


def test_a_stream_of_joint_states_is_drawn_moving_between_them(open_view: Callable[..., Page], iva: Habitat) -> None:
    """States that come as a stream are drawn moving between them, never past
    the newest one (nothing is extrapolated: an arm that halts is not drawn beyond where it stopped),
    and the arm ends drawn exactly at the last. With interpolation off every frame shows a state as
    it came."""
    page = open_view(iva.document(), clock=True)
    # An installed clock still flows with the real one: paused, the page's time moves only by
    # run_for, so a loaded machine cannot stretch the 0.2 s between states into a gap that ends
    # the stream (it did, in a heavily loaded run: no frame drawn between states).
    page.clock.pause_at(page.evaluate("Date.now()") + 1)
    start = inspect(page)["joints"]["wrist_3_joint"]
    sent = [start + 0.1 * k for k in range(1, 11)]

    watched = _stream(page, True, sent)
    drawn = [d for d, _ in watched["frames"]]
    states = [watched["start"], *sent]
    for (value, newest), previous in zip(watched["frames"], [watched["start"], *drawn], strict=False):
        assert previous - 1e-9 <= value <= newest + 1e-9, f"drawn {value} after {previous}, the newest state {newest}"
    between = [d for d in drawn if min(abs(d - state) for state in states) > 1e-6]
    # At least one move drawn between states (with the clock paused, each state's move is drawn
    # over the frames of its 0.2 s).
    assert between, f"no frame between states in {len(drawn)} frames: {drawn}"
    assert drawn[-1] == sent[-1]

    back = list(reversed([start, *sent[:-1]]))
    watched = _stream(page, False, back)
    shown = {d for d, _ in watched["frames"]}
    assert shown <= {sent[-1], *back}, (
        f"without interpolation frames showed {sorted(shown - {sent[-1], *back})}, which no state said"
    )
    assert watched["frames"][-1][0] == back[-1]


def test_a_moving_arm_is_drawn_at_most_at_the_frame_cap_and_a_still_view_asks_for_no_frames(
    open_view: Callable[..., Page], iva: Habitat
) -> None:
    """While joint states stream at 10/s the view draws the arm between them at no more than its cap
    (25 frames/s: each frame is tens of ms of CPU in software), and more often than states come;
    once the arm is drawn where the last state put it the view stops asking for animation frames
    (an idle page asking for each one kept Chromium busy)."""
    page = open_view(iva.document(), clock=True)
    page.clock.pause_at(page.evaluate("Date.now()") + 1)
    page.clock.run_for(1000)
    still = inspect(page)
    assert still["max_frame_rate"] == 25 and not still["animating"], still
    start = still["joints"]["wrist_3_joint"]
    for k in range(1, 21):  # two seconds of states
        page.evaluate(SEND, start + 0.05 * k)
        page.clock.run_for(100)
    frames = inspect(page)["frames"] - still["frames"]
    assert 20 < frames <= 2 * 25 + 1, f"{frames} frames drawn in 2 s of a stream of 10 states a second"
    page.clock.run_for(1000)
    settled = inspect(page)
    assert settled["settled"] and not settled["animating"], settled
    assert settled["joints"]["wrist_3_joint"] == start + 0.05 * 20
    page.clock.run_for(1000)
    assert inspect(page)["frames"] == settled["frames"], "a still view went on drawing"


def test_the_arm_drawn_says_its_age_from_the_moment_a_state_comes(open_view: Callable[..., Page], iva: Habitat) -> None:
    """A joint state's age is said as it comes, not at the next frame (under load a frame comes late,
    and an arm shown without its age reads as the arm now); the clock running on, the age grows."""
    page = open_view(iva.document(), clock=True)
    page.clock.pause_at(page.evaluate("Date.now()") + 1)
    said = page.evaluate(
        """() => {
      const view = window.caretakerSpatial;
      view.apply({kind: 'joints', stamp: Date.now() / 1000 - 1.3, positions: {wrist_3_joint: 0.2}});
      return view.ageEl.hidden ? null : view.ageEl.textContent;  // no frame ran in between
    }"""
    )
    assert said == "arm as reported 1.3 s ago"
    page.clock.run_for(2000)
    later = re.fullmatch(r"arm as reported (\d+\.\d) s ago", page.locator(".ct-spatial-age").text_content() or "")
    assert later and 3.3 - 0.25 <= float(later[1]) <= 3.3, later  # said four times a second


def test_an_emergency_action_s_frame_is_not_held_by_the_view_which_draws_the_frame_after(
    open_view: Callable[..., Page], iva: Habitat
) -> None:
    """HALT's "halting…" goes out in the next frame without the 3D view's drawing (tens of ms in
    software while the arm moves); the change is drawn in the frame after."""
    page = open_view(iva.document())
    drawn(page)
    frames = page.evaluate(
        """() => new Promise((done) => {
      const view = window.caretakerSpatial;
      const counted = [view.inspect().frames];
      view.yieldFrames(2);
      view.apply({kind: 'joints', stamp: Date.now() / 1000, positions: {wrist_3_joint: 0.4}});
      const next = () => requestAnimationFrame(() => {
        counted.push(view.inspect().frames);
        if (counted.length < 5) next(); else done(counted);
      });
      next();
    })"""
    )
    # the view's own frame callback runs before the test's in each frame: two frames without drawing
    assert frames[1] == frames[2] == frames[0], frames
    assert frames[4] > frames[0], f"the view did not draw the change after yielding: {frames}"


def test_malformed_input_is_refused_whole(open_view: Callable[..., Page], iva: Habitat) -> None:
    page = open_view(iva.document())
    before = inspect(page)["links"]
    refused = page.evaluate(
        "(u) => window.caretakerSpatial.apply(u)", {"kind": "joints", "positions": {"elbow_joint": "fast"}}
    )
    assert refused is False
    assert "update.positions.elbow_joint: expected a finite number" in page.evaluate("window.viewErrors")[-1]
    assert inspect(page)["links"] == before
    error = page.evaluate("""() => { try { window.caretakerSpatial.load({contract: 1, kind: 'scene'}); return null; }
                                     catch (e) { return e.message; } }""")
    assert error == "scene.frame: expected a non-empty string, got undefined"
    hollow = {**iva.document(), "robot": {**iva.document()["robot"], "urdf": "<robot name='hollow'/>"}}
    error = page.evaluate(
        "(d) => { try { window.caretakerSpatial.load(d); return null; } catch (e) { return e.message; } }", hollow
    )
    assert error == "robot ur10: the URDF has no links"
    assert page.evaluate("window.viewErrors")[-1] == "scene document refused: robot ur10: the URDF has no links"
    assert inspect(page)["robot"] == "ur10" and inspect(page)["links"] == before, (
        "a refused document must leave the view as it was"
    )
    assert page.evaluate("window.caretakerSpatial.dragBy('nothing:0', {translate: [0.05, 0, 0]})") == {
        "refused": "nothing named nothing:0"
    }
    assert page.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0')") == {
        "refused": "nothing named cdra_filter:0"
    }


# -------------------------------------------------------------------------------- templates


def test_objects_and_templates_at_their_poses(open_view: Callable[..., Page], iva: Habitat) -> None:
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    page = open_view(iva.document())
    apply(page, running.update("grasp_and_pull"))
    state = inspect(page)

    for name, (xyz, quat) in iva.sim.frames():
        if name in state["objects"]:
            assert_pose(state["objects"][name]["pose"], matrix({"xyz": xyz, "quat": quat}), f"object {name}")
    assert {"rack", "cabinet", "table", "filter/CDRA-F-0007", "filter/CDRA-F-0012", "cabinet/latch"} <= set(
        state["objects"]
    )

    templates = state["templates"]
    assert_pose(templates["cdra_filter:0"]["pose"], running.instance.object_pose("cdra_filter"), "display object")
    assert_pose(templates["cdra_filter:0"]["pose"], iva.frame("cabinet/slot"), "display object on the cabinet slot")
    resolved = running.resolved("grasp_and_pull")
    assert [k for k, v in templates.items() if v["kind"] == "waypoint"] == [wp.label for wp in resolved]
    for wp in resolved:
        assert_pose(templates[wp.label]["pose"], wp.frame_pose, f"waypoint {wp.label}")

    labels = page.locator(".ct-spatial-label")
    assert "cdra_filter:0" in labels.all_text_contents() and "0.3:cdra_filter:0" in labels.all_text_contents()
    assert page.locator(".ct-spatial-label-waypoint").first.is_visible()
    page.click("[data-action=names]")
    assert not page.locator(".ct-spatial-label-waypoint").first.is_visible()
    assert inspect(page)["names_visible"] is False

    apply(page, {"kind": "templates", "templates": []})
    assert inspect(page)["templates"] == {}

    # The habitat moves a filter (/sim/frames): only that object follows.
    frames = iva.frames_json()
    index = frames["names"].index("filter/CDRA-F-0007")
    frames["poses"][index]["position"] = {"x": 0.5, "y": 0.4, "z": 1.2}
    apply(page, objects_update(frames))
    moved = inspect(page)["objects"]
    assert moved["filter/CDRA-F-0007"]["pose"]["xyz"] == pytest.approx([0.5, 0.4, 1.2], abs=1e-6)
    assert moved["rack"] == state["objects"]["rack"]


@pytest.mark.parametrize("width, height", [(440, 340), (360, 340), (1000, 700)])
def test_names_leave_the_display_object_in_sight_and_lie_on_nothing(
    open_view: Callable[..., Page], iva: Habitat, screenshots: Path, width: int, height: int
) -> None:
    """The console's 3D panel at 1500 px (440 wide) and at 1024 px (360), and the view alone."""
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    page = open_view(iva.document())
    page.set_viewport_size({"width": width, "height": height})
    apply(page, running.update("grasp_and_pull"))
    plan = running.plan("grasp_and_pull", [float(v) for v in iva.mapping["robot"]["initial_positions"]])
    apply(page, plan)  # the plan player's controls join the bar: names keep off them too
    found = names_hide_nothing(page, "cdra_filter:0", f"{width}x{height}")
    print(
        f"{width}x{height}: {found['visible']:.0%} of the display object visible with names on, "
        f"{found['placed']} names shown, {found['unplaced']} without room"
    )
    assert page.locator(".ct-spatial-label-display_object", has_text="cdra_filter:0").is_visible()
    page.screenshot(path=str(screenshots / f"spatial_names_{width}.png"))


#: The table's top, world frame (sim/scenes/iva.yaml: a 1.0 x 0.8 x 0.04 m box at z 0.73).
TABLE_TOP = (np.array([-0.5, -0.4, 0.71]), np.array([0.5, 0.4, 0.75]))


def test_what_hides_the_gripper_fades_and_follows_it_as_the_arm_moves(
    open_view: Callable[..., Page], iva: Habitat
) -> None:
    """The robot's tool is kept in sight like the point looked at: a scene object between the eye
    and the gripper fades (a gripper reaching into a cabinet stays visible), and as the arm moves
    what fades follows the tool."""
    document = iva.document()
    document["templates"] = []
    page = open_view(document)
    page.evaluate("window.caretakerSpatial.setJointInterpolation(false)")
    tool = np.array(inspect(page)["tool_pose"]["xyz"])
    centre = (TABLE_TOP[0] + TABLE_TOP[1]) / 2
    eye = tool + 2.0 * (centre - tool)  # under the table, the gripper above it
    away = eye + 0.05 * (eye - tool) / np.linalg.norm(eye - tool)  # looking away from it: only the tool's line crosses
    assert crosses(TABLE_TOP, eye, tool) and not crosses(TABLE_TOP, eye, away)
    page.evaluate(
        """([eye, target]) => {
      const view = window.caretakerSpatial;
      view.camera.position.set(...eye);
      view.orbit.target.set(...target);
      view.orbit.update();
    }""",
        [eye.tolist(), away.tolist()],
    )
    drawn(page)
    assert "table" in inspect(page)["camera"]["faded"]

    # the arm stretched out to the side: the line to the tool passes beside the table, which shows again
    turned = {"shoulder_pan_joint": -1.5708, "shoulder_lift_joint": -0.6, "elbow_joint": 0.3}
    apply(page, {"kind": "joints", "stamp": 1.0, "positions": turned})
    moved = np.array(inspect(page)["tool_pose"]["xyz"])
    assert np.linalg.norm(moved - tool) > 0.1 and not crosses(TABLE_TOP, eye, moved)
    assert "table" not in inspect(page)["camera"]["faded"]


def test_camera_image_beside_the_scene(open_view: Callable[..., Page], iva: Habitat, site: SpatialSite) -> None:
    site.files["/camera.png"] = ((REPO / "docs" / "images" / "scene_iva.png").read_bytes(), "image/png")
    page = open_view(iva.document())
    assert inspect(page)["camera_url"] is None and page.locator(".ct-spatial-camera").is_hidden()
    apply(page, {"kind": "camera", "url": "/camera.png?seq=1"})
    assert inspect(page)["camera_url"] == "/camera.png?seq=1"
    assert shown_image_width(page.locator(".ct-spatial-camera")) > 0
    apply(page, {"kind": "camera", "url": None})
    assert page.locator(".ct-spatial-camera").is_hidden()


# ------------------------------------------------------------------------------------- plan


def test_plan_ghost_plays_scrubs_and_steps(open_view: Callable[..., Page], iva: Habitat, screenshots: Path) -> None:
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    document = iva.document()
    page = open_view(document)
    apply(page, running.update("grasp_and_pull"))
    update = running.plan("grasp_and_pull", iva_start(iva))
    plan = update["plan"]
    apply(page, update)
    names = plan["joint_names"]

    def ghost_at_point(k: int, what: str) -> None:
        ghost = inspect(page)["ghost"]
        assert ghost["time"] == pytest.approx(plan["points"][k]["time_from_start"], abs=1e-9), what
        assert [ghost["joints"][n] for n in names] == pytest.approx(plan["points"][k]["positions"], abs=1e-9), what
        fk = iva.link_poses(
            {**document["joints"]["positions"], **dict(zip(names, plan["points"][k]["positions"], strict=True))}
        )
        assert_pose(ghost["tool_pose"], fk["tool0"], f"{what}: ghost tool")

    ghost = inspect(page)["ghost"]
    assert ghost["visible"] and not ghost["playing"]
    assert_pose(ghost["tool_pose"], matrix(plan["end_pose"]), "the ghost's last pose is the plan's end pose")
    ghost_at_point(len(plan["points"]) - 1, "a new plan shows its end")
    page.screenshot(path=str(screenshots / "spatial_iva.png"))

    # Closing the gripper moves no joint: two waypoints share a point, one stop.
    stops = sorted({w["point"] for w in plan["waypoints"]})
    assert len(stops) < len(plan["waypoints"])
    for k in reversed([0, *stops[:-1]]):
        page.click("[data-action=previous-waypoint]")
        ghost_at_point(k, f"previous waypoint -> point {k}")
    page.click("[data-action=next-waypoint]")
    ghost_at_point(stops[0], "next waypoint from the start")
    assert inspect(page)["ghost"]["waypoint"] == plan["waypoints"][0]["name"]

    # The slider scrubs through time: half-way is the joint path interpolated at half the duration.
    page.locator(".ct-spatial-plan input[type=range]").fill("500")
    ghost = inspect(page)["ghost"]
    duration = plan["points"][-1]["time_from_start"]
    assert ghost["time"] == pytest.approx(duration / 2, abs=1e-9)
    times = [p["time_from_start"] for p in plan["points"]]
    expected = [
        float(np.interp(duration / 2, times, [p["positions"][j] for p in plan["points"]])) for j in range(len(names))
    ]
    assert [ghost["joints"][n] for n in names] == pytest.approx(expected, abs=1e-9)
    # The gripper closes at waypoint 2: before it, the ghost's fingers are the scene's "open".
    assert ghost["joints"]["gripper_left_finger_joint"] == pytest.approx(0.0425)

    page.click("[data-action=play]")
    page.wait_for_function("!window.caretakerSpatial.inspect().ghost.playing")
    ghost_at_point(len(plan["points"]) - 1, "played to the end")
    assert inspect(page)["ghost"]["joints"]["gripper_left_finger_joint"] == pytest.approx(0.0)

    apply(page, {"kind": "plan", "plan": None})  # after Execute the ghost goes
    assert inspect(page)["ghost"] == {"visible": False}
    assert page.locator(".ct-spatial-plan").is_hidden()


def test_a_running_plan_is_drawn_as_the_path_ahead_and_its_end_reached_only_when_reported(
    open_view: Callable[..., Page], iva: Habitat
) -> None:
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    page = open_view(iva.document())
    apply(page, running.update("grasp_and_pull"))
    plan = running.plan("grasp_and_pull", iva_start(iva))["plan"]
    names, points = plan["joint_names"], plan["points"]
    apply(page, {"kind": "plan", "plan": {**plan, "commanded": True}})  # the habitat executes it
    state = inspect(page)
    assert state["ghost"] == {"visible": False}, "a running plan is no ghost to play"
    commanded = state["commanded"]
    assert commanded["visible"] and not commanded["reached"]
    assert commanded["end"] == pytest.approx(list(matrix(plan["end_pose"])[:3, 3]), abs=MM)

    def reported(point: dict[str, Any], stamp: float) -> dict[str, Any]:
        return {"kind": "joints", "stamp": stamp, "positions": dict(zip(names, point["positions"], strict=True))}

    apply(page, reported(points[len(points) // 2], 1.0))
    assert not inspect(page)["commanded"]["reached"], "half-way reported: the end is not reached"
    apply(page, reported(points[-1], 2.0))
    assert inspect(page)["commanded"]["reached"], "the arm reported at the end"
    apply(page, {"kind": "plan", "plan": None})  # executed
    assert inspect(page)["commanded"] == {"visible": False}

    refused = page.evaluate(
        "(u) => window.caretakerSpatial.apply(u)", {"kind": "plan", "plan": {**plan, "commanded": "yes"}}
    )
    assert refused is False
    assert "update.plan.commanded: expected true or false" in page.evaluate("window.viewErrors")[-1]


# ---------------------------------------------------------------------------- registration


def _command_pose(args: dict[str, Any]) -> np.ndarray:
    return from_xyz_rpy([args["x"], args["y"], args["z"]], [args["roll"], args["pitch"], args["yaw"]])


def test_operator_drag_asks_and_waits_for_the_server(open_view: Callable[..., Page], iva: Habitat) -> None:
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    page = open_view(iva.document(), can_act=True)
    apply(page, running.update("grasp_and_pull"))
    slot = iva.frame("cabinet/slot")
    start = running.instance.object_pose("cdra_filter")

    result = page.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0', {translate: [0.05, 0, 0]})")
    assert "refused" not in result
    commands = page.evaluate("window.commands")
    assert len(commands) == 1
    command = commands[0]
    moved = start.copy()
    moved[:3, 3] += [0.05, 0.0, 0.0]
    assert command["command"] == "set_display_object_pose"
    args = command["args"]
    assert {k: args[k] for k in ("affordance_template", "id", "display_object", "frame")} == {
        "affordance_template": "cdra_filter",
        "id": 0,
        "display_object": "cdra_filter",
        "frame": "cabinet/slot",
    }
    assert_pose(command["pose"], moved, "requested pose in the document frame")
    assert_pose(
        {"xyz": [args["x"], args["y"], args["z"]], "quat": list(_quat(_command_pose(args)))},
        invert(slot) @ moved,
        "requested pose in the slot frame",
    )

    # Not committed locally: the object stays where the server has it, the request is pending.
    state = inspect(page)
    assert_pose(state["templates"]["cdra_filter:0"]["pose"], start, "object before the server answers", position=1e-6)
    assert state["registration"]["pending"]["cdra_filter:0"]["state"] == "sent"

    # The AT server registers it as set_object_pose does (frame pose x requested offset): confirmed.
    running.register("cdra_filter", args["frame"], _command_pose(args))
    apply(page, running.update("grasp_and_pull"))
    state = inspect(page)
    assert state["registration"]["pending"] == {}
    assert_pose(state["templates"]["cdra_filter:0"]["pose"], moved, "object after the server moved it")

    # A waypoint: pose relative to its display object (frame_id ""), as set_waypoint_pose reads it.
    label = "0.1:cdra_filter:0"
    before = next(wp for wp in running.resolved("grasp_and_pull") if wp.label == label).frame_pose
    page.evaluate(f"window.caretakerSpatial.dragBy('{label}', {{translate: [0, 0, 0.05]}})")
    command = page.evaluate("window.commands")[-1]
    assert command["command"] == "set_waypoint_pose"
    args = command["args"]
    assert {k: args[k] for k in ("affordance_template", "id", "trajectory", "waypoint_id", "ee_name", "frame_id")} == {
        "affordance_template": "cdra_filter",
        "id": 0,
        "trajectory": "grasp_and_pull",
        "waypoint_id": 1,
        "ee_name": "gripper",
        "frame_id": "",
    }
    trajectory = running.instance.trajectory(args["trajectory"])
    ee = running.instance.end_effector(trajectory, [args["ee_name"]])
    parent = running.instance.object_pose("cdra_filter")
    running.instance.set_waypoint(trajectory, ee, args["waypoint_id"], parent @ _command_pose(args))
    expected = before.copy()
    expected[:3, 3] += [0.0, 0.0, 0.05]
    after = next(wp for wp in running.resolved("grasp_and_pull") if wp.label == label).frame_pose
    assert_pose(
        {"xyz": list(after[:3, 3]), "quat": list(_quat(after))}, expected, "waypoint where the AT server puts it"
    )
    apply(page, running.update("grasp_and_pull"))
    assert inspect(page)["registration"]["pending"] == {}

    # Reported done, but the next update shows the object elsewhere: the request snaps back.
    page.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0', {rotate: [0, 0, 0.3]})")
    page.evaluate("window.caretakerSpatial.resolvePending('cdra_filter:0', 'succeeded')")
    assert inspect(page)["registration"]["pending"]["cdra_filter:0"]["state"] == "succeeded"
    apply(page, running.update("grasp_and_pull"))
    state = inspect(page)
    assert state["registration"]["pending"] == {}
    assert "shows it elsewhere" in state["last_error"]
    assert_pose(state["templates"]["cdra_filter:0"]["pose"], moved, "object stays where the server has it")

    # A failed command drops its pending pose at once.
    page.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0', {translate: [0, 0.02, 0]})")
    page.evaluate("window.caretakerSpatial.resolvePending('cdra_filter:0', 'failed')")
    assert inspect(page)["registration"]["pending"] == {}

    # Releasing without moving asks for nothing.
    sent = len(page.evaluate("window.commands"))
    assert page.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0', {})") == {"command": None}
    assert len(page.evaluate("window.commands")) == sent


def _quat(m: np.ndarray) -> np.ndarray:
    return quat_from_matrix(m[:3, :3])


def _pointer_drag(page: Page, name: str, dx: float, dy: float) -> None:
    """Click ``name`` to select it, then drag from its centre (the handles' free-move grip)."""
    point = page.evaluate(f"window.caretakerSpatial.screenPoint('{name}')")
    page.mouse.click(point["x"], point["y"])
    drawn(page)  # the handles are placed when drawn
    page.mouse.move(point["x"], point["y"])
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(point["x"] + dx * k / 10, point["y"] + dy * k / 10)
    page.mouse.up()


def test_pointer_drag_sends_a_command(open_view: Callable[..., Page], iva: Habitat) -> None:
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    page = open_view(iva.document(), can_act=True)
    apply(page, running.update("grasp_and_pull"))
    start = running.instance.object_pose("cdra_filter")
    _pointer_drag(page, "cdra_filter:0", 60, -40)
    commands = page.evaluate("window.commands")
    assert [c["command"] for c in commands] == ["set_display_object_pose"]
    requested = matrix(commands[0]["pose"])
    assert np.linalg.norm(requested[:3, 3] - start[:3, 3]) > 0.01, "a 70 px drag moves the object by more than 1 cm"
    assert_pose(
        inspect(page)["templates"]["cdra_filter:0"]["pose"], start, "object before the server answers", position=1e-6
    )


def test_observer_can_move_nothing(open_view: Callable[..., Page], iva: Habitat) -> None:
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    page = open_view(iva.document(), can_act=False)
    apply(page, running.update("grasp_and_pull"))
    result = page.evaluate("window.caretakerSpatial.dragBy('cdra_filter:0', {translate: [0.05, 0, 0]})")
    assert "observers cannot move" in result["refused"]
    accepted = page.evaluate("window.caretakerSpatial.accept('cdra_filter:0')")
    assert "observers cannot accept" in accepted["refused"]
    _pointer_drag(page, "cdra_filter:0", 60, -40)
    state = inspect(page)
    assert page.evaluate("window.commands") == []
    assert state["registration"] == {
        "can_act": False,
        "selected": None,
        "mode": "translate",
        "pending": {},
        "proposals": {},
        "located": None,
        "handles": False,
    }
    assert page.locator("[data-action=mode]").is_hidden()
    assert_pose(
        state["templates"]["cdra_filter:0"]["pose"],
        running.instance.object_pose("cdra_filter"),
        "object",
        position=1e-6,
    )


# -------------------------------------------------------------------------------------- EVA


def _drawn_fraction(page: Page) -> float:
    """Share of canvas pixels that differ from the background: the scene was really drawn."""
    return page.evaluate(
        """() => {
        const d = ("""
        + READ_PIXELS
        + """)(window.caretakerSpatial);
        let drawn = 0;
        for (let i = 0; i < d.length; i += 4)
            if (Math.abs(d[i] - 0x1d) + Math.abs(d[i + 1] - 0x21) + Math.abs(d[i + 2] - 0x27) > 24) drawn++;
        return drawn / (d.length / 4);
    }"""
    )


def test_eva_arm_and_hull_targets_render(open_view: Callable[..., Page], eva: Habitat, screenshots: Path) -> None:
    running = RunningTemplate.add(eva, "inspection", "eva_arm", object_name="target", frame="target/hull_a")
    document = eva.document()
    page = open_view(document)
    apply(page, running.update("inspect"))
    plan = running.plan("inspect", [float(v) for v in eva.mapping["robot"]["initial_positions"]], seconds_per_step=0.5)
    apply(page, plan)
    state = inspect(page)
    assert state["robot"] == "eva_arm"
    assert_links(state["links"], eva.link_poses(document["joints"]["positions"]), "EVA arm")
    for target in eva.mapping["targets"]:
        name = f"target/{target['name']}"
        assert_pose(state["objects"][name]["pose"], from_xyz_rpy(target["pose"]["xyz"], target["pose"]["rpy"]), name)
    assert_pose(state["templates"]["target:0"]["pose"], eva.frame("target/hull_a"), "inspection target on hull_a")
    assert_pose(state["ghost"]["tool_pose"], matrix(plan["plan"]["end_pose"]), "EVA ghost at the plan's end")
    assert _drawn_fraction(page) > 0.05
    page.screenshot(path=str(screenshots / "spatial_eva.png"))


# ------------------------------------------------------------------------------- frame rate


def _frame_rate(page: Page, updates: int) -> tuple[float, float, float, float]:
    """Frames/s, joint updates/s, seconds and the median ms from a joint update to the frame showing
    it, while ``updates`` joint updates arrive (counted, not timed)."""
    probe = (
        "[performance.now(), window.caretakerSpatial.inspect().frames, window.caretakerSpatial.inspect().joint_updates]"
    )
    before = page.evaluate(probe)
    page.wait_for_function(f"window.caretakerSpatial.inspect().joint_updates >= {before[2] + updates}")
    after = page.evaluate(probe)
    latency = page.evaluate("window.caretakerSpatial.inspect().update_latency_ms")
    seconds = (after[0] - before[0]) / 1000
    assert after[1] > before[1], "the view rendered no frame while joints streamed"
    assert latency is not None, "no frame showed a joint update"
    return (after[1] - before[1]) / seconds, (after[2] - before[2]) / seconds, seconds, latency


#: (joint updates/s, on demand, adaptive resolution, joint interpolation) of each measurement: the
#: console's way at 50/s and at 10/s (the rate the ground server forwards).
CONSOLE_MODES = ((50, True, True, True), (10, True, True, True))
#: bench/spatial_frame_rate.py (CARETAKER_FRAME_RATE_MODES=all) compares them with every frame at
#: full resolution, every frame adaptive, and 10/s drawn as each state arrives.
ALL_MODES = (
    (50, False, False, True),
    (50, False, True, True),
    (50, True, True, True),
    (10, True, True, False),
    (10, True, True, True),
)


def test_frame_rate_while_joints_stream(
    open_view: Callable[..., Page], iva: Habitat, record_property: Callable[[str, Any], None]
) -> None:
    """Reports frames/s and update-to-frame latency while joint updates stream, side by side in one
    page (a measurement, not a timed assertion; the suite measures the console's way, the benchmark
    every mode). Frames are drawn while joints stream, each at the resolution its mode allows, and
    once the stream stops the view draws at full resolution again."""
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    page = open_view(iva.document())
    apply(page, running.update("grasp_and_pull"))
    apply(page, running.plan("grasp_and_pull", iva_start(iva)))
    lines = []
    rate_now = 0
    modes = ALL_MODES if os.environ.get("CARETAKER_FRAME_RATE_MODES") == "all" else CONSOLE_MODES
    for rate, on_demand, adaptive, interpolate in modes:
        if rate != rate_now:
            page.evaluate(
                "([hz, names, base]) => { window.stopJointStream(); window.startJointStream(hz, names, base); }",
                [rate, iva.arm_joints, iva_start(iva)],
            )
            rate_now = rate
        page.evaluate(
            f"window.caretakerSpatial.setRenderOnDemand({str(on_demand).lower()});"
            f"window.caretakerSpatial.setAdaptiveResolution({str(adaptive).lower()});"
            f"window.caretakerSpatial.setJointInterpolation({str(interpolate).lower()})"
        )
        if not inspect(page)["names_visible"]:
            page.click("[data-action=names]")
        _frame_rate(page, rate)  # the resolution adapts first
        fps, measured_rate, seconds, latency = _frame_rate(page, 3 * rate)
        scale = inspect(page)["resolution_scale"]
        assert adaptive or scale == 1, f"drawn at {scale} of full resolution with adaptive resolution off"
        page.click("[data-action=names]")
        fps_unnamed, _, _, _ = _frame_rate(page, 2 * rate)
        mode = (
            f"{rate}hz_"
            + ("on_demand" if on_demand else "every_frame")
            + ("_adaptive" if adaptive else "")
            + ("_interpolated" if interpolate else "")
        )
        record_property(f"spatial_fps_{mode}", round(fps, 1))
        record_property(f"spatial_latency_ms_{mode}", round(latency, 1))
        lines.append(
            f"{mode}: {fps:.1f} frames/s ({fps_unnamed:.1f} with names hidden) at {scale:.2f} of full resolution, "
            f"update-to-frame median {latency:.0f} ms, joint updates at {measured_rate:.1f}/s over {seconds:.1f} s"
        )
    page.evaluate("window.stopJointStream()")
    # still again: the arm drawn at the last state (a move toward it lasts one interval after the
    # stream stops), sharp
    page.wait_for_function("(s => s.settled && s.resolution_scale === 1)(window.caretakerSpatial.inspect())")
    load = os.getloadavg()[0]
    print(
        f"\nspatial view (1000x700, SwiftShader, load average {load:.1f} on {os.cpu_count()} cores):\n  "
        + "\n  ".join(lines)
    )
    state = inspect(page)
    assert_links(state["links"], iva.link_poses(state["joints"]), "after streaming")
