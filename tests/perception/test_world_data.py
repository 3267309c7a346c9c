"""Markers and displacement as data: a scene's markers checked where they are written, and a
displaced world that moves what it says it moves, consistently, and nothing without a seed.

In-process (the scene loader and the simulation's world, no ROS)."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pybullet as p
import pytest
import yaml

from sim.displacement import MAX_ANGLE_RAD, MAX_OFFSET_M, compose, displaced_objects, displaced_scene
from sim.scene import SCENES_DIR, Pose, SceneError, load_scene
from sim.simulation import Simulation
from sim.world import seated_filter_collisions

pytestmark = pytest.mark.slow(seconds=10)

IVA = (SCENES_DIR / "iva.yaml").read_text()


def test_the_displaced_objects_are_the_slot_bodies_and_targets() -> None:
    assert displaced_objects(load_scene("iva")) == ["rack", "cabinet"]
    assert displaced_objects(load_scene("eva")) == [f"target/hull_{c}" for c in "abcd"]


@pytest.mark.parametrize("scene", ["iva", "eva"])
def test_without_a_seed_the_world_is_the_scene(scene: str) -> None:
    sim = Simulation(load_scene(scene))
    try:
        assert sim.frames() == sim.true_frames()
    finally:
        sim.close()


def _offset(nominal: tuple, real: tuple) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """``real`` in the frame of ``nominal``: position (m) and roll/pitch/yaw (rad)."""
    inv = p.invertTransform(*nominal)
    position, orientation = p.multiplyTransforms(inv[0], inv[1], *real)
    return tuple(position), tuple(p.getEulerFromQuaternion(orientation))


def test_a_displaced_iva_moves_rack_and_cabinet_with_their_slots_and_filters() -> None:
    sim = Simulation(load_scene("iva"), displace=3)
    try:
        said, real = dict(sim.frames()), dict(sim.true_frames())
        for slot in ("rack/slot_1", "rack/slot_2", "rack/slot_3", "cabinet/slot"):
            assert said[slot] != real[slot]
        # the three rack slots moved as one body: their offsets from each other are the drawings'
        position, angles = _offset(real["rack/slot_1"], real["rack/slot_3"])
        assert position == pytest.approx((0.0, 0.5, 0.0), abs=1e-6) and angles == pytest.approx((0, 0, 0), abs=1e-6)
        # each seated filter where its slot really is; the world model says where the drawings put it
        for filter_id, slot in (("CDRA-F-0012", "rack/slot_1"), ("CDRA-F-0007", "cabinet/slot")):
            seated = real[f"filter/{filter_id}"]
            assert seated[0] == pytest.approx(real[slot][0]) and seated[1] == pytest.approx(real[slot][1])
            assert said[f"filter/{filter_id}"] == said[slot]
        # the robot, its tool and its cameras are where they are for both
        for frame in ("robot_base", "tool0", "camera/wrist_camera", "camera/scene"):
            assert said[frame] == real[frame]
    finally:
        sim.close()


def test_a_displaced_world_never_puts_a_filter_into_another_body() -> None:
    """The cabinet is on a wall: moved 4 cm toward it, its seated filter would be 1 cm into the
    wall, and the pull-out would scrape it out of there. Such a draw is drawn again."""
    scene = load_scene("iva")
    assert seated_filter_collisions(scene) == []
    toward_the_wall = Pose((0.05, 0.0, 0.0), (0.0, 0.0, 0.0))  # the cabinet's x is into its slot, toward the wall
    cabinet = next(b for b in scene.bodies if b.name == "cabinet")
    pushed = replace(
        scene,
        bodies=tuple(replace(b, pose=compose(b.pose, toward_the_wall)) if b is cabinet else b for b in scene.bodies),
        slots={
            **scene.slots,
            "cabinet/slot": replace(scene.slots["cabinet/slot"], pose=compose(cabinet.pose, toward_the_wall)),
        },
    )
    assert seated_filter_collisions(pushed) == ["filter/CDRA-F-0007 in module"]
    for seed in range(20):
        assert seated_filter_collisions(displaced_scene(scene, seed)) == [], seed


def test_every_offset_is_within_the_bounds_and_seeds_differ() -> None:
    scene = load_scene("eva")
    worlds = []
    for seed in (1, 2):
        sim = Simulation(scene, displace=seed)
        try:
            said, real = dict(sim.frames()), dict(sim.true_frames())
            offsets = [_offset(said[f"target/hull_{c}"], real[f"target/hull_{c}"]) for c in "abcd"]
        finally:
            sim.close()
        for position, angles in offsets:
            assert max(map(abs, position)) <= MAX_OFFSET_M + 1e-9
            # fixed-axis angles of a composed rotation: within the bound up to second-order terms
            assert max(map(abs, angles)) <= MAX_ANGLE_RAD + math.radians(1.0)
            assert max(map(abs, position)) > 1e-3 or max(map(abs, angles)) > 1e-3
        worlds.append(offsets)
    assert worlds[0] != worlds[1]
    again = Simulation(scene, displace=1)
    try:
        assert [
            _offset(dict(again.frames())[f"target/hull_{c}"], dict(again.true_frames())[f"target/hull_{c}"])
            for c in "abcd"
        ] == worlds[0]
    finally:
        again.close()


def _scene_with(tmp_path: Path, old: str, new: str) -> Path:
    assert old in IVA
    path = tmp_path / "iva.yaml"
    text = IVA.replace(old, new).replace("urdf: ../robots/", f"urdf: {SCENES_DIR.parent / 'robots'}/")
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("old", "new", "problem"),
    [
        ("frame: rack/slot_1, xyz: [-0.0705, 0.0, -0.17]", "frame: rack/slot_9, xyz: [-0.0705, 0.0, -0.17]",
         "markers[0].frame: unknown frame 'rack/slot_9'; markers are fixed to one of module, table, rack"),
        ("{id: 2, size: 0.10", "{id: 1, size: 0.10", "markers[1]: marker '1' is defined twice"),
        ("{id: 1, size: 0.10", "{id: 600, size: 0.10", "markers[0].id:"),
        ("{id: 1, size: 0.10", "{id: 1, size: -0.1", "markers[0].size:"),
        ("marker_dictionary: DICT_APRILTAG_36h11", "marker_dictionary: DICT_APRILTAG_99",
         "marker_dictionary: unknown marker dictionary 'DICT_APRILTAG_99'; OpenCV's are DICT_4X4_100"),
        ("{id: 1, size: 0.10,", "{id: 1, size: 0.10, colour: red,", "markers[0].colour: unknown key 'colour'"),
        ("{name: wrist_camera,", "{name: wrist-camera,", "cameras[1].name: 'wrist-camera' is not a ROS name"),
    ],
)  # fmt: skip
def test_a_bad_marker_declaration_is_one_line_naming_file_line_and_key(
    tmp_path: Path, old: str, new: str, problem: str
) -> None:
    path = _scene_with(tmp_path, old, new)
    lines = {n for n, text in enumerate(path.read_text().splitlines(), 1) if new.split(",")[0] in text}
    with pytest.raises(SceneError) as error:
        load_scene(path)
    where, _, what = str(error.value).partition(": ")
    assert where.rpartition(":")[0] == str(path) and int(where.rpartition(":")[2]) in lines, str(error.value)
    assert problem in what, str(error.value)
    checked = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "check", str(path)], capture_output=True, text=True, check=False
    )
    assert checked.returncode == 1 and "Traceback" not in checked.stdout + checked.stderr
    assert f"{where}: {what}" in checked.stdout


def test_the_shipped_iva_scene_marks_every_slot_and_filter() -> None:
    data = yaml.safe_load(IVA)
    assert {m["frame"] for m in data["markers"]} == {
        "rack/slot_1", "rack/slot_2", "rack/slot_3", "cabinet/slot",
        "filter/CDRA-F-0012", "filter/CDRA-F-0013", "filter/CDRA-F-0007",
    }  # fmt: skip
