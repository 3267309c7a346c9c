"""AT library loader: the shipped templates, the original format, and errors naming file and key."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from at_ros.library import (
    PLANNER_CARTESIAN,
    PLANNER_JOINT,
    LibraryError,
    default_library_path,
    load_library,
    load_template,
)

# The original package's cube.json (data format only), as in the notes.
CUBE = {
    "name": "Cube",
    "image": "package://affordance_template_library/images/cube.png",
    "display_objects": [
        {
            "name": "cube",
            "shape": {
                "type": "box",
                "material": {"color": "red", "rgba": [0.0, 1.0, 0.0, 1.0]},
                "size": [0.04, 0.08, 0.08],
            },
            "origin": {"xyz": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 1.57]},
            "controls": {"xyz": [True, True, True], "rpy": [True, True, True], "scale": 0.1},
        }
    ],
    "end_effector_trajectory": [
        {
            "name": "Hand Top Grasp",
            "end_effector_group": [
                {
                    "id": 0,
                    "end_effector_waypoint": [
                        {
                            "ee_pose": 0,
                            "display_object": "cube",
                            "origin": {"xyz": [0.0, 0.0, -0.16], "rpy": [0.0, -1.57, -1.57]},
                            "controls": {"xyz": [True, True, True], "rpy": [True, True, True], "scale": 0.1},
                            "planner_type": "JOINT",
                        },
                        {
                            "ee_pose": 3,
                            "display_object": "cube",
                            "origin": {"xyz": [0.0, 0.0, -0.02], "rpy": [0.0, -1.57, -1.57]},
                            "controls": {"xyz": [1, 1, 1], "rpy": [1, 1, 1], "scale": 0.1},
                        },
                    ],
                }
            ],
        }
    ],
}


def write(tmp_path: Path, data: object, name: str = "t.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return path


def test_shipped_library_has_the_task_templates() -> None:
    library = load_library(default_library_path() / "templates")
    assert {"cdra_filter", "ready_pose", "inspection"} <= set(library)
    cdra = library["cdra_filter"]
    assert {"grasp_and_pull", "insert_and_release"} <= set(cdra.trajectory_names)
    pull = cdra.trajectory("grasp_and_pull").group(0).waypoints
    assert pull[0].planner_type == PLANNER_JOINT  # the first waypoint avoids obstacles, as in the original
    assert [w.ee_pose for w in pull] == [0, 0, 1, 1]  # open, open, close, keep closed while pulling
    assert library["inspection"].trajectory("inspect") is not None
    for template in library.values():  # every package:// image the library names exists
        assert template.image.startswith("package://at_ros/library/images/")
        assert (default_library_path() / "images" / Path(template.image).name).is_file()


def test_original_cube_file_loads_with_parser_defaults(tmp_path: Path) -> None:
    template = load_template(write(tmp_path, CUBE))
    assert template.name == "Cube"
    waypoints = template.trajectory("Hand Top Grasp").group(0).waypoints
    assert waypoints[0].planner_type == PLANNER_JOINT
    assert waypoints[1].planner_type == PLANNER_CARTESIAN  # the parser's default
    assert waypoints[1].controls.xyz == (True, True, True)  # 0/1 accepted like booleans
    assert waypoints[1].tolerances.position == pytest.approx(0.01)
    assert waypoints[0].origin.xyz == (0.0, 0.0, -0.16)


def _broken(mutate: Callable[[dict], object]) -> dict:
    data = json.loads(json.dumps(CUBE))
    mutate(data)
    return data


WAYPOINT = "end_effector_trajectory[0].end_effector_group[0].end_effector_waypoint[1]"


@pytest.mark.parametrize(
    ("mutate", "key", "problem"),
    [
        (lambda d: d.pop("name"), "name", "missing required key"),
        (
            lambda d: d["end_effector_trajectory"][0]["end_effector_group"][0]["end_effector_waypoint"][1].pop(
                "origin"
            ),
            f"{WAYPOINT}.origin",
            "missing required key",
        ),
        (
            lambda d: d["end_effector_trajectory"][0]["end_effector_group"][0]["end_effector_waypoint"][1].update(
                planner_type="JIONT"
            ),
            f"{WAYPOINT}.planner_type",
            "JIONT",
        ),
        (
            lambda d: d["end_effector_trajectory"][0]["end_effector_group"][0]["end_effector_waypoint"][1].update(
                display_object="cubee"
            ),
            f"{WAYPOINT}.display_object",
            "unknown display object 'cubee'",
        ),
        (
            lambda d: d["end_effector_trajectory"][0]["end_effector_group"][0]["end_effector_waypoint"][1].update(
                ee_pose="open"
            ),
            f"{WAYPOINT}.ee_pose",
            "expected an integer",
        ),
        (lambda d: d["display_objects"][0]["origin"].update(xyz=[0, 0]), "display_objects[0].origin.xyz", "3 numbers"),
        (
            lambda d: d["display_objects"][0]["shape"].update(type="torus"),
            "display_objects[0].shape.type",
            "unknown value 'torus'",
        ),
        (
            lambda d: d["display_objects"][0].update(parent="table"),
            "display_objects[0].parent",
            "unknown display object 'table'",
        ),
        (
            lambda d: d.update(end_effector_trajectories=d.pop("end_effector_trajectory")),
            "end_effector_trajectories",
            "singular",
        ),
        (
            lambda d: d["end_effector_trajectory"].append(d["end_effector_trajectory"][0]),
            "end_effector_trajectory[1].name",
            "defined twice",
        ),
        (
            lambda d: d["end_effector_trajectory"][0]["end_effector_group"][0]["end_effector_waypoint"][1].update(
                grap="cube"
            ),
            f"{WAYPOINT}.grap",
            "unknown key 'grap'",
        ),
        (
            lambda d: d["end_effector_trajectory"][0]["end_effector_group"][0]["end_effector_waypoint"][1].update(
                grasp="lid"
            ),
            f"{WAYPOINT}.grasp",
            "unknown display object 'lid'",
        ),
        (
            lambda d: d["end_effector_trajectory"][0]["end_effector_group"][0]["end_effector_waypoint"][1].update(
                grasp="cube", release="cube"
            ),
            f"{WAYPOINT}.release",
            "not both",
        ),
        (
            lambda d: d["display_objects"][0]["origin"].update(xyz=[0, 0, float("nan")]),
            "",
            "NaN and Infinity are not JSON numbers",
        ),
        (
            lambda d: d["display_objects"][0]["origin"].update(xyz=[0, 0, 1e400]),
            "",
            "NaN and Infinity are not JSON numbers",
        ),
        (
            lambda d: d["display_objects"][0]["origin"].update(xyz=[0, 0, "1"]),
            "display_objects[0].origin.xyz[2]",
            "expected a number, got str '1'",
        ),
    ],
)
def test_malformed_template_names_file_and_key(
    tmp_path: Path, mutate: Callable[[dict], object], key: str, problem: str
) -> None:
    path = write(tmp_path, _broken(mutate))
    with pytest.raises(LibraryError) as err:
        load_template(path)
    assert err.value.key == key
    assert str(path) in str(err.value)
    assert problem in str(err.value)


def test_json_syntax_error_names_line_and_column(tmp_path: Path) -> None:
    path = write(tmp_path, '{\n  "name": "x",\n  "image": ,\n}')
    with pytest.raises(LibraryError, match=r"t\.json:3:\d+: not valid JSON"):
        load_template(path)


def test_library_rejects_two_files_with_one_name(tmp_path: Path) -> None:
    write(tmp_path, CUBE, "a.json")
    write(tmp_path, CUBE, "b.json")
    with pytest.raises(LibraryError, match=r"b\.json: name: template name 'Cube' is already used by .*a\.json"):
        load_library(tmp_path)


def test_library_keys_by_name_and_searches_subfolders(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    write(tmp_path, CUBE, "sub/whatever.json")
    assert list(load_library(tmp_path)) == ["Cube"]


def test_the_error_names_the_line_of_the_key(tmp_path: Path) -> None:
    path = write(
        tmp_path, json.dumps(_broken(lambda d: d["display_objects"][0]["shape"].update(type="torus")), indent=2)
    )
    with pytest.raises(LibraryError) as err:
        load_template(path)
    line = path.read_text().splitlines()[err.value.line - 1]
    assert '"torus"' in line and str(err.value).startswith(f"{path}:{err.value.line}: ")


def test_a_linked_folder_in_the_library_is_followed_and_a_loop_refused(tmp_path: Path) -> None:
    shared = tmp_path / "shared"
    shared.mkdir()
    write(shared, CUBE, "cube.json")
    library = tmp_path / "library"
    library.mkdir()
    (library / "shared").symlink_to(shared, target_is_directory=True)
    assert list(load_library(library)) == ["Cube"]
    (shared / "back").symlink_to(library, target_is_directory=True)
    with pytest.raises(LibraryError, match=r"back: linked folder leads back into the library"):
        load_library(library)


def test_grasp_and_release_are_read_with_defaults_for_the_original_format(tmp_path: Path) -> None:
    assert all(
        not w.grasp and not w.release for w in load_template(write(tmp_path, CUBE)).trajectories[0].groups[0].waypoints
    )
    cdra = load_library(default_library_path() / "templates")["cdra_filter"]
    pull = cdra.trajectory("grasp_and_pull").group(0).waypoints
    assert [w.grasp for w in pull] == ["", "", "cdra_filter", ""]
    assert [w.release for w in cdra.trajectory("insert_and_release").group(0).waypoints] == ["", "", "cdra_filter", ""]


def test_missing_library_folder_is_reported(tmp_path: Path) -> None:
    with pytest.raises(LibraryError, match="does not exist"):
        load_library(tmp_path / "nope")
