"""AT server state on disk: instances come back as they were, plans do not, bad files are named."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from at_ros.instance import ExecutionOutcome, Registration, StoredPlan, TemplateInstance
from at_ros.instance_store import load_instances, save_instances
from at_ros.library import LibraryError, Template
from at_ros.robot_config import RobotConfig
from at_ros.transforms import from_xyz_rpy
from support.processes import COMMAND_HANG_S


def _worked_instance(library: dict[str, Template], ur10_config: RobotConfig) -> TemplateInstance:
    """An instance an operator has set up: registered, one waypoint moved, partly executed, planned."""
    instance = TemplateInstance(
        library["cdra_filter"], 3, ur10_config, from_xyz_rpy([0.6, 0, 0.3], [0, 0, 0.1]), hide_waypoints=True
    )
    slot = from_xyz_rpy([0.15, 0.90, 1.05], [0.0, 0.0, np.pi / 2])
    instance.register("cdra_filter", Registration("cabinet/slot", from_xyz_rpy([0.01, 0, 0], [0, 0, 0]), slot))
    trajectory = instance.trajectory("insert_and_release")
    instance.set_waypoint(
        trajectory, instance.end_effector(trajectory, []), 1, from_xyz_rpy([0.2, 0.7, 1.0], [0, 0.2, 0])
    )
    instance.current_trajectory = "insert_and_release"
    instance.progress["grasp_and_pull"].current_index = 2
    instance.progress["grasp_and_pull"].outcome = ExecutionOutcome.HALTED
    instance.progress["grasp_and_pull"].outcome_message = "halted (operator): stopped after waypoint 2"
    instance.plan = StoredPlan("insert_and_release", "gripper", [0, 1], [], {}, {}, "")
    return instance


def test_instances_come_back_as_they_were_without_their_plan(
    tmp_path: Path, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    before = _worked_instance(library, ur10_config)
    path = tmp_path / "state" / "at_server.json"
    save_instances(path, ur10_config, {before.key: before})
    restored = load_instances(path, ur10_config, library)
    assert list(restored) == ["cdra_filter:3"]
    after = restored["cdra_filter:3"]
    assert (after.hide_waypoints, after.current_trajectory) == (True, "insert_and_release")
    assert (
        after.progress["grasp_and_pull"].current_index == 2 and after.progress["insert_and_release"].current_index == -1
    )
    # How the last execution ended comes back too: the next plan of grasp_and_pull resumes after waypoint 2.
    assert (
        after.progress["grasp_and_pull"].interrupted
        and "stopped after waypoint 2" in after.progress["grasp_and_pull"].outcome_message
    )
    assert not after.progress["insert_and_release"].interrupted
    assert after.plan is None  # a plan belongs to its moment: planned again after a restart
    np.testing.assert_allclose(after.root_pose, before.root_pose)
    assert after.registrations["cdra_filter"].frame == "cabinet/slot"
    for name in ("grasp_and_pull", "insert_and_release"):
        trajectory = before.trajectory(name)
        ee = before.end_effector(trajectory, [])
        for a, b in zip(before.resolve(trajectory, ee), after.resolve(trajectory, ee), strict=True):
            np.testing.assert_allclose(b.tool_goal, a.tool_goal, atol=1e-12)
    assert [p.name for p in path.parent.iterdir()] == ["at_server.json"]  # no temporary file left behind


def test_no_state_file_yet_is_no_instances(
    tmp_path: Path, library: dict[str, Template], ur10_config: RobotConfig
) -> None:
    assert load_instances(tmp_path / "absent.json", ur10_config, library) == {}


@pytest.mark.parametrize(
    ("edit", "problem"),
    [
        (lambda d: d.update(robot="eva_arm"), r"robot: state of robot 'eva_arm', but this server serves 'ur10'"),
        (
            lambda d: d["instances"][0].update(template="crate"),
            r"instances\[0\]\.template: template 'crate' is not in the library",
        ),
        (
            lambda d: d["instances"][0].update(root_pose=[1, 2, 3]),
            r"instances\[0\]\.root_pose: expected at least 4 items, got 3",
        ),
        (
            lambda d: d["instances"][0]["root_pose"][0].__setitem__(0, "NaN"),
            r"instances\[0\]\.root_pose\[0\]\[0\]: expected a number, got str 'NaN'",
        ),
        (
            lambda d: d["instances"][0]["registrations"].update(lid=d["instances"][0]["registrations"]["cdra_filter"]),
            r"instances\[0\]: cannot be restored: template 'cdra_filter' has no display object 'lid'",
        ),
        (lambda d: d.update(format=7), r"format: expected AT server state format 1"),
        (
            lambda d: d["instances"][0]["executions"]["grasp_and_pull"].update(outcome="PAUSED"),
            r"instances\[0\]\.executions\.grasp_and_pull\.outcome: unknown outcome 'PAUSED'; "
            r"expected one of EXECUTING, SUCCEEDED, FAILED, HALTED",
        ),
    ],
)
def test_a_state_file_that_cannot_be_restored_is_named_with_the_entry(
    tmp_path: Path, library: dict[str, Template], ur10_config: RobotConfig, edit: Callable[[dict], object], problem: str
) -> None:
    instance = _worked_instance(library, ur10_config)
    path = tmp_path / "at_server.json"
    save_instances(path, ur10_config, {instance.key: instance})
    document = json.loads(path.read_text())
    edit(document)
    path.write_text(json.dumps(document))
    with pytest.raises(LibraryError, match=rf"at_server\.json:1: {problem}"):
        load_instances(path, ur10_config, library)


def test_the_server_refuses_to_start_on_state_it_cannot_restore(tmp_path: Path, ros_env: dict[str, str]) -> None:
    state = tmp_path / "at_server.json"
    state.write_text(json.dumps({"format": 1, "robot": "eva_arm", "instances": []}))
    server = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "at-server", "--robot", "ur10", "--state-file", str(state)],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=COMMAND_HANG_S,
    )
    assert server.returncode == 2
    assert f"{state}:1: robot: state of robot 'eva_arm', but this server serves 'ur10'" in server.stderr
