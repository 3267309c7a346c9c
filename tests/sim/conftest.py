"""One simulator process per test module (starting one takes seconds), plus a ROS client."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from sim_client import SimClient

from support.processes import ManagedProcess, caretaker


def _start_sim(scene: str, env: dict[str, str], capture_dir: Path) -> ManagedProcess:
    proc = caretaker(
        "sim",
        "--scene",
        scene,
        "--time-scale",
        "0",
        "--seed",
        "7",
        "--camera-period",
        "1",
        "--capture-dir",
        str(capture_dir),
        env=env,
        name=f"sim-{scene}",
    )
    proc.wait_ready(90.0)
    return proc


@pytest.fixture(scope="module")
def capture_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("captures")


@pytest.fixture(scope="module")
def sim_process(request: pytest.FixtureRequest, ros_env: dict[str, str], capture_dir: Path) -> Iterator[ManagedProcess]:
    """The simulator for the scene named by the module's ``SCENE``, stopped after the module."""
    proc = _start_sim(request.module.SCENE, ros_env, capture_dir)
    try:
        yield proc
    finally:
        code = proc.stop()
        print(f"--- {proc.name} output ---\n{proc.tail(200)}")  # shown by pytest when a test failed
        assert code == 0, f"sim exited with {code} on Ctrl-C; its output:\n{proc.tail()}"


@pytest.fixture(scope="module")
def client(sim_process: ManagedProcess) -> Iterator[SimClient]:
    c = SimClient()
    try:
        yield c
    finally:
        c.close()
