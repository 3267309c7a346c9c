"""Fixtures of the AT server and planner suites."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from at_ros.collision_scene import build_planning_scene
from at_ros.library import default_library_path, load_library
from at_ros.robot_config import load_robot_config, load_robot_configs
from sim.collision_world import collision_world
from sim.scene import load_scene

#: The UR10's start pose in the IVA scene file (sim/scenes/iva.yaml).
UR10_START = np.array([0.0, -1.9, 1.9, -1.570796, -1.570796, 0.0])


@pytest.fixture(scope="module")
def library():
    return load_library(default_library_path() / "templates")


@pytest.fixture(scope="module")
def ur10_config():
    return load_robot_configs()["ur10"]


@pytest.fixture(scope="module")
def iva_scene(ur10_config):
    """The planner's pybullet world for the IVA scene, from the collision world the simulation publishes."""
    scene = build_planning_scene(ur10_config, collision_world(load_scene("iva")))
    yield scene
    scene.close()


def start_stack(ros_env: dict[str, str], deployment: str, time_scale: float):
    """The deployment's simulation, planner and AT server as real processes, plus a test client; stops them all."""
    from support.stack import robot_parts

    from at_client import AtClient

    with robot_parts(deployment, ros_env, parts=("sim", "planner", "at-server"), time_scale=time_scale):
        client = AtClient()
        try:
            client.wait_for(lambda: client.status is not None and client.status.planner_node_active and bool(client.frames), 60.0, "server status with an active planner")
            yield client
        finally:
            client.close()


BENCH_ARM = Path(__file__).resolve().parents[1] / "fixtures" / "bench_arm"


def bench_planning_scene(urdf_edit=None, tmp_path: Path | None = None):
    """The bench arm of tests/fixtures/bench_arm (a robot not shipped) on its workbench; with
    ``urdf_edit`` (text -> text) on a copy of its URDF in ``tmp_path``."""
    import dataclasses

    config = load_robot_config(BENCH_ARM / "bench_arm.yaml")
    if urdf_edit is not None:
        assert tmp_path is not None
        urdf = tmp_path / "bench_arm.urdf"
        urdf.write_text(urdf_edit(config.urdf.read_text()))
        config = dataclasses.replace(config, urdf=urdf)
    return config, build_planning_scene(config, collision_world(load_scene(BENCH_ARM / "workbench.yaml")))
