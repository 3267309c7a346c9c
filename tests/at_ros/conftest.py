"""Fixtures of the AT server and planner suites."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from at_ros.collision_scene import build_planning_scene
from at_ros.library import Template, default_library_path, load_library
from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import RobotConfig, load_robot_configs
from sim.collision_world import collision_world
from sim.scene import load_scene
from support.planning_scenes import bench_planning_scene


@pytest.fixture(scope="module")
def library() -> dict[str, Template]:
    return load_library(default_library_path() / "templates")


@pytest.fixture(scope="module")
def ur10_config() -> RobotConfig:
    return load_robot_configs()["ur10"]


@pytest.fixture(scope="module")
def iva_scene(ur10_config: RobotConfig) -> Iterator[PlanningScene]:
    """The planner's pybullet world for the IVA scene, from the collision world the simulation publishes."""
    scene = build_planning_scene(ur10_config, collision_world(load_scene("iva")))
    yield scene
    scene.close()


@pytest.fixture
def narrow_wrist_bench(tmp_path: Path) -> Iterator[tuple[RobotConfig, PlanningScene]]:
    """The bench arm with its wrist roll narrowed to +-1 rad: the flipped wrist (roll about +-2.5)
    is no longer allowed, so a grasp in front of the shelf needs a joint beyond its range."""

    def narrow(urdf: str) -> str:
        return urdf.replace(
            '<limit lower="-3.0" upper="3.0" effort="50" velocity="2.5"/>',
            '<limit lower="-1.0" upper="1.0" effort="50" velocity="2.5"/>',
        )

    config, scene = bench_planning_scene(narrow, tmp_path)
    yield config, scene
    scene.close()
