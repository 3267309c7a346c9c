"""Robot configs: the original YAML keys plus planner settings; errors name file and key."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from at_ros.library import LibraryError, default_library_path
from at_ros.robot_config import load_robot_config, load_robot_configs


def test_shipped_robots_load_with_files_that_exist() -> None:
    robots = load_robot_configs()
    assert set(robots) >= {"ur10", "eva_arm"}
    ur10 = robots["ur10"]
    assert ur10.urdf.is_file()
    assert len(ur10.joint_names) == 6 and len(robots["eva_arm"].joint_names) == 7
    assert ur10.pose_name("gripper", 0) == "open" and ur10.pose_name("gripper", 1) == "closed"
    assert ur10.end_effector_by_id(0).name == "gripper"
    assert ur10.root_offset_matrix[0, 3] == pytest.approx(ur10.root_offset[0])
    assert ur10.halt_service == robots["eva_arm"].halt_service == "robot/halt"


def _config(tmp_path: Path, **changes: Any) -> Path:
    data = yaml.safe_load((default_library_path() / "robots" / "ur10.yaml").read_text())
    data["urdf"] = str(load_robot_configs()["ur10"].urdf)  # the copy lives elsewhere: its path must still lead there
    for key, value in changes.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("changes", "key", "problem"),
    [
        ({"robot_name": None}, "robot_name", "missing required key"),
        ({"root_offset": [0, 0, 1]}, "root_offset", "6 numbers"),
        (
            {"end_effector_pose_map": [{"name": "open", "group": "hand", "id": 0}]},
            "end_effector_pose_map[0].group",
            "unknown end effector 'hand'",
        ),
        ({"joint_names": []}, "joint_names", "expected at least 1 item"),
        ({"planner": {"plan_tme": 1.0}}, "planner.plan_tme", "unknown key 'plan_tme'"),
        ({"planner": {"plan_time": -1}}, "planner.plan_time", "below the minimum"),
        ({"scene": "sim/scenes/iva.yaml"}, "scene", "unknown key 'scene'"),
        ({"urdf": "no/such.urdf"}, "urdf", "no such file"),
    ],
)
def test_malformed_robot_config_names_file_and_key(tmp_path: Path, changes: dict, key: str, problem: str) -> None:
    path = _config(tmp_path, **changes)
    with pytest.raises(LibraryError) as err:
        load_robot_config(path)
    assert err.value.key == key and problem in str(err.value) and str(path) in str(err.value)


def test_yaml_syntax_error_names_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("robot_name: x\nroot_offset: [0, 0\n")
    with pytest.raises(LibraryError, match=r"bad\.yaml:\d+: not valid YAML"):
        load_robot_config(path)


def test_two_files_claiming_one_robot_name_are_refused_naming_both(tmp_path: Path) -> None:
    for name in ("a_ur10.yaml", "b_ur10.yaml"):
        _config(tmp_path).rename(tmp_path / name)
    with pytest.raises(
        LibraryError, match=r"b_ur10\.yaml: robot_name: robot robot_name 'ur10' is already used by .*a_ur10\.yaml"
    ):
        load_robot_configs(tmp_path)
