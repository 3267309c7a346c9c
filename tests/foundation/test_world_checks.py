"""World checks as data (a deployment's ``demo.checks``): read at load time, judged from samples.

Every wrong check is one ``file:line: key: problem`` line when the deployment loads, naming what
to write instead; the frames and targets a check names are checked against the deployment's
scene. Judging is measured on frames as the simulation publishes them (here written by hand),
with one line in words per check.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from caretaker.deployment import DeploymentError, load_deployment
from caretaker.world_checks import (
    TOPIC_TIMEOUT,
    FrameCheck,
    ImagesCheck,
    Place,
    TelemetryCheck,
    WorldWatch,
    _World,
    scene_frames,
)
from caretaker.world_checks import _frames as _world_frames
from sim.scene import load_scene
from support.stack import write_deployment

REPO = Path(__file__).resolve().parents[2]
DEMO = (
    "demo:\n"
    f"  procedure: {REPO / 'procedures' / 'iva_cdra_filter_replacement.xml'}\n"
    f"  binding: {REPO / 'sysrep' / 'bindings' / 'iva.yaml'}\n"
    "  inputs: {clean_filter_id: CDRA-F-0012}\n"
    "  checks:\n"
)


def _with_checks(tmp_path: Path, *items: str) -> tuple[Path, int]:
    """The shipped IVA deployment with ``items`` as its demo checks; the line of the first item."""
    path = write_deployment(tmp_path, "iva", demo=None)
    text = path.read_text() + DEMO
    path.write_text(text + "".join(f"    - {item}\n" for item in items))
    return path, text.count("\n") + 1


def test_the_shipped_checks_are_data() -> None:
    iva = load_deployment("iva").demo
    assert iva is not None and iva.checks == (
        FrameCheck("filter/CDRA-F-0007", Place("rack/slot_3"), within_mm=30.0, within_deg=None, during_run=False),
        TelemetryCheck("cdra/installed_filter_id", "CDRA-F-0012"),  # ${clean_filter_id} from the inputs
        TelemetryCheck("cdra/filter_locked", True),
    )
    eva = load_deployment("eva").demo
    assert eva is not None and eva.checks == (ImagesCheck(None),)


def test_a_pose_in_a_frame_reads_as_written(tmp_path: Path) -> None:
    path, _ = _with_checks(
        tmp_path,
        "{tool: tool0, visits: {frame: robot_base, xyz: [0.4, 0.1, 0.3], rpy: [0, 1.5, 0]}, "
        "within_mm: 5, within_deg: 2}",
    )
    demo = load_deployment(path).demo
    assert demo is not None and demo.checks == (
        FrameCheck("tool0", Place("robot_base", (0.4, 0.1, 0.3), (0.0, 1.5, 0.0), named=False), 5.0, 2.0, True),
    )


@pytest.mark.parametrize(
    ("item", "key", "problem"),
    [
        ("{within_mm: 30}", "demo.checks[1]", "a check names one of object, tool, topic, images_of"),
        (
            "{object: filter/CDRA-F-0007, tool: tool0, at: rack/slot_3, within_mm: 3}",
            "demo.checks[1]",
            "got object, tool",
        ),
        ("{object: filter/CDRA-F-0007, at: rack/slot_3}", "demo.checks[1].within_mm", "missing required key"),
        (
            "{object: filter/CDRA-F-0007, at: rack/slot_3, within_mm: -1}",
            "demo.checks[1].within_mm",
            "below the minimum",
        ),
        ("{object: filter/CDRA-F-0007, within_mm: 30}", "demo.checks[1]", "'at' (at the end of the run) or 'visits'"),
        (
            "{object: filter/CDRA-F-0007, at: rack/slot_3, visits: rack/slot_3, within_mm: 30}",
            "demo.checks[1]",
            "'at' (at the end of the run) or 'visits'",
        ),
        (
            "{object: filter/CDRA-F-0007, at: rack/slot_3, within_mm: 30, colour: red}",
            "demo.checks[1].colour",
            "unknown key",
        ),
        ("{object: filter/NOPE, at: rack/slot_3, within_mm: 30}", "demo.checks[1].object", "no object 'filter/NOPE'"),
        ("{object: filter/CDRA-F-0007, at: rack/slot_9, within_mm: 30}", "demo.checks[1].at", "no frame 'rack/slot_9'"),
        (
            "{tool: tool9, at: rack/slot_1, within_mm: 5}",
            "demo.checks[1].tool",
            "the tool of scene iva.yaml is 'tool0'",
        ),
        (
            "{tool: tool0, visits: {frame: nowhere, xyz: [0, 0, 1]}, within_mm: 5}",
            "demo.checks[1].visits.frame",
            "no frame",
        ),
        ("{tool: tool0, visits: {xyz: [0, 0]}, within_mm: 5}", "demo.checks[1].visits.xyz", "a list of 3 numbers"),
        (
            "{tool: tool0, at: rack/slot_1, within_mm: 5, within_deg: 270}",
            "demo.checks[1].within_deg",
            "above the maximum",
        ),
        (
            '{topic: cdra/installed_filter_id, equals: "${clean_id}"}',
            "demo.checks[1].equals",
            "${clean_id} is not one of the demo's inputs (clean_filter_id)",
        ),
        ("{topic: cdra/installed_filter_id}", "demo.checks[1].equals", "missing required key"),
        ("{images_of: every targets}", "demo.checks[1].images_of", "expected 'every target' or a list"),
        ("{images_of: [hull_a]}", "demo.checks[1].images_of", "scene iva.yaml has no targets to image"),
    ],
)
def test_a_wrong_check_is_one_line_at_its_own_line(tmp_path: Path, item: str, key: str, problem: str) -> None:
    path, line = _with_checks(tmp_path, "{topic: cdra/filter_locked, equals: true}", item)
    with pytest.raises(DeploymentError) as refused:
        load_deployment(path)
    message = str(refused.value)
    assert message.startswith(f"{path}:{line + 1}: {key}: "), message  # the second item's line
    assert problem in message and "\n" not in message, message


def test_checks_must_be_a_list(tmp_path: Path) -> None:
    path = write_deployment(tmp_path, "iva", demo=None)
    path.write_text(path.read_text() + DEMO.replace("  checks:\n", "  checks: cdra_filters_swapped\n"))
    with pytest.raises(DeploymentError, match=r"demo\.checks: expected a list, got"):
        load_deployment(path)


def test_a_target_the_scene_lacks_is_named(tmp_path: Path) -> None:
    path = write_deployment(tmp_path, "eva")
    path.write_text(path.read_text().replace("images_of: every target", "images_of: [hull_a, hull_z]"))
    with pytest.raises(
        DeploymentError, match=r"demo\.checks\[0\]\.images_of\[1\]: scene eva\.yaml has no target 'hull_z'"
    ):
        load_deployment(path)


def test_the_frames_a_scene_publishes_are_those_of_the_interface() -> None:
    frames = scene_frames(load_scene("iva"))
    assert frames[:2] == ["robot_base", "tool0"]
    assert {"filter/CDRA-F-0007", "rack/slot_3", "cabinet/slot", "camera/scene"} <= set(frames)
    assert {"target/hull_a", "camera/ee_camera"} <= set(scene_frames(load_scene("eva")))


def _pose(x: float, y: float, z: float, yaw_deg: float = 0.0) -> dict[str, Any]:
    half = math.radians(yaw_deg) / 2
    return {
        "position": {"x": x, "y": y, "z": z},
        "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)},
    }


def _frames(poses: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """A sim/frames message as rosbridge delivers it."""
    return {"names": list(poses), "poses": list(poses.values())}


class _Recorded(_World):
    """The robot side as recorded samples: what the watch saw during the run, and the newest of each topic."""

    def __init__(
        self, visits: tuple[FrameCheck, ...], during: list[dict[str, Any]], newest: dict[str, dict[str, Any]]
    ) -> None:
        super().__init__(None, "", visits)
        for message in during:
            self._keep(message)  # as the watch's subscription is called
        self._newest = newest

    def truth(self) -> dict[str, Any]:
        return _world_frames(self.newest("/sim/check/frames"))

    def newest(self, topic: str, msg_type: str | None = None) -> dict[str, Any]:
        if topic not in self._newest:
            raise LookupError(f"no message on {topic} within {TOPIC_TIMEOUT:g} s")
        return self._newest[topic]


def test_each_check_is_judged_in_words_with_rounded_values() -> None:
    scene = load_scene("iva")
    base = _pose(0.0, 0.0, 0.75)
    end = _frames(
        {
            "robot_base": base,
            "tool0": _pose(0.5, 0.0, 1.0),
            "rack/slot_3": _pose(0.96, 0.25, 1.05),
            "filter/CDRA-F-0007": _pose(0.964, 0.25, 1.05),
        }
    )
    during = [
        _frames({"robot_base": base, "tool0": _pose(0.3, 0.0, 1.2)}),
        _frames({"robot_base": base, "tool0": _pose(0.402, 0.1, 1.05, yaw_deg=1.0)}),  # the pose, 2 mm and 1° off
        _frames({"robot_base": base, "tool0": _pose(0.5, 0.0, 1.0)}),
    ]
    checks = (
        FrameCheck("filter/CDRA-F-0007", Place("rack/slot_3"), 30.0, None, during_run=False),
        FrameCheck("tool0", Place("robot_base", (0.4, 0.1, 0.3), named=False), 5.0, 2.0, during_run=True),
        FrameCheck("tool0", Place("robot_base", (0.4, -0.1, 0.3), named=False), 5.0, 2.0, during_run=True),
        FrameCheck("tool0", Place("rack/slot_3"), 5.0, None, during_run=False),
        TelemetryCheck("cdra/installed_filter_id", "CDRA-F-0012"),
        TelemetryCheck("cdra/filter_locked", True),
        TelemetryCheck("/cdra/missing", 1),
    )
    world = _Recorded(
        tuple(c for c in checks if isinstance(c, FrameCheck) and c.during_run),
        during,
        {
            "/sim/check/frames": end,
            "/cdra/installed_filter_id": {"data": "CDRA-F-0012"},
            "/cdra/filter_locked": {"data": False},
        },
    )
    verdicts = WorldWatch(checks, world, scene).judge("sqlite://", "run")
    assert [(v.holds, v.words) for v in verdicts] == [
        (True, "filter/CDRA-F-0007 is at rack/slot_3: 4 mm from it (within 30 mm)"),
        (True, "tool0 reached (400, 100, 300) mm in robot_base: 2 mm, 1.0° from it (within 5 mm, 2°)"),
        (
            False,
            "tool0 never reached (400, -100, 300) mm in robot_base in 4 samples of the run; "
            "nearest: 150 mm, 0.0° from it (within 5 mm, 2°)",
        ),
        (False, "tool0 is not at rack/slot_3: 526 mm from it (within 5 mm)"),
        (True, "/cdra/installed_filter_id is 'CDRA-F-0012'"),
        (False, "/cdra/filter_locked is False, expected True"),
        (False, f"no message on /cdra/missing within {TOPIC_TIMEOUT:g} s"),
    ]
    # the robot side unreachable: every check that reads it says so, nothing is guessed
    unreachable = WorldWatch(checks[:1], "cannot watch the robot side through ws://x:1: refused", scene)
    assert [v.words for v in unreachable.judge("sqlite://", "run")] == [
        "cannot watch the robot side through ws://x:1: refused"
    ]
