"""Robots in scenes for the planner tests: the UR10's start pose in the IVA scene, and the bench arm
of tests/fixtures/bench_arm (a robot not shipped) on its workbench."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from at_ros.collision_scene import build_planning_scene
from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import RobotConfig, load_robot_config
from sim.collision_world import collision_world
from sim.scene import load_scene

__all__ = ["BENCH_ARM", "UR10_START", "bench_planning_scene"]

#: The UR10's start pose in the IVA scene file (sim/scenes/iva.yaml).
UR10_START = np.array([0.0, -1.9, 1.9, -1.570796, -1.570796, 0.0])

BENCH_ARM = Path(__file__).resolve().parents[1] / "fixtures" / "bench_arm"


def bench_planning_scene(
    urdf_edit: Callable[[str], str] | None = None, tmp_path: Path | None = None
) -> tuple[RobotConfig, PlanningScene]:
    """The bench arm of tests/fixtures/bench_arm (a robot not shipped) on its workbench; with
    ``urdf_edit`` (text -> text) on a copy of its URDF in ``tmp_path``."""
    config = load_robot_config(BENCH_ARM / "bench_arm.yaml")
    if urdf_edit is not None:
        assert tmp_path is not None
        urdf = tmp_path / "bench_arm.urdf"
        urdf.write_text(urdf_edit(config.urdf.read_text()))
        config = dataclasses.replace(config, urdf=urdf)
    return config, build_planning_scene(config, collision_world(load_scene(BENCH_ARM / "workbench.yaml")))
