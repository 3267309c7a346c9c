"""The SysRep loader: Fig. 1 loads unchanged, extensions are accepted, every error names file and entry."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from procedure_language.limits import Limits, Persistence
from procedure_language.sysrep import SysRepError, check_value, load_sysrep, load_sysrep_dir

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "tests" / "fixtures" / "sysrep"
EXPECTED = yaml.safe_load((FIXTURES / "invalid" / "expected_errors.yaml").read_text())

# Fig. 1 of the paper, transcribed independently of the YAML file.
FIG1_COMMANDS = [
    (
        "add_affordance_template",
        "Add Affordance Template",
        [("affordance_template", "string"), ("hide_waypoints", "boolean")],
    ),
    (
        "delete_affordance_template",
        "Delete Affordance Template",
        [("affordance_template", "string"), ("id", "integer")],
    ),
    ("plan_trajectory", "Plan Trajectory", [("affordance_template", "string"), ("trajectory", "string")]),
    ("execute_plan", "Execute Plan", [("affordance_template", "string"), ("trajectory", "string")]),
    (
        "set_waypoint_pose",
        "Set Waypoint Pose",
        [
            ("affordance_template", "string"),
            ("id", "integer"),
            ("trajectory", "string"),
            ("waypoint_id", "integer"),
            ("ee_name", "string"),
            ("x", "real"),
            ("y", "real"),
            ("z", "real"),
            ("roll", "real"),
            ("pitch", "real"),
            ("yaw", "real"),
            ("frame_id", "string"),
        ],
    ),
    (
        "set_display_object_pose",
        "Set Display Object Pose",
        [
            ("affordance_template", "string"),
            ("id", "integer"),
            ("display_object", "string"),
            ("frame", "string"),
            ("x", "real"),
            ("y", "real"),
            ("z", "real"),
            ("roll", "real"),
            ("pitch", "real"),
            ("yaw", "real"),
        ],
    ),
]
FIG1_TELEMETRY = [
    ("robot_active", "Robot Active", "boolean"),
    ("planner_node_active", "Planner Node Active", "boolean"),
    ("affordance_template_server_active", "Affordance Template Server Active", "boolean"),
    ("execute_status", "Execution Status", "string"),
    ("plan_status", "Plan Status", "string"),
    ("plan_valid", "Plan Valid", "boolean"),
]


def test_fig1_sysrep_is_verbatim() -> None:
    sysrep = load_sysrep(REPO / "sysrep" / "affordance_templates.yaml")
    assert sysrep.id == "affordance_templates"
    assert sysrep.name == "CRAFTSMAN AffordanceTemplates YAML"
    assert [(c.id, c.label, [(a.name, a.type) for a in c.args]) for c in sysrep.commands] == FIG1_COMMANDS
    assert [(t.id, t.label, t.type) for t in sysrep.telemetry] == FIG1_TELEMETRY
    assert not any(c.hazardous for c in sysrep.commands)


def test_every_shipped_sysrep_loads() -> None:
    sysreps = load_sysrep_dir(REPO / "sysrep")
    assert "affordance_templates" in sysreps


def test_extensions_are_read() -> None:
    sysrep = load_sysrep(FIXTURES / "valid" / "extensions.yaml")
    move = sysrep.command("move_to")
    assert move is not None and move.hazardous and move.description == "Moves the arm"
    x = move.arg("x")
    assert x is not None and (x.units, x.min, x.max) == ("m", -2.0, 2.0)
    assert move.arg("mode").enum == ("fast", "slow")
    assert sysrep.telemetry_item("state").enum == ("IDLE", "BUSY")
    force, grasped = sysrep.telemetry_item("force").limits, sysrep.telemetry_item("grasped").limits
    assert force == Limits(yellow_high=30.0, red_high=40.0, persistence=Persistence(seconds=2.0))
    assert [force.state(v) for v in (25, 35, 45)] == ["green", "yellow", "red"]
    assert grasped == Limits(equals=True, persistence=Persistence(samples=3))
    assert (grasped.state(True), grasped.state(False), force.describe("red")) == ("green", "red", "red above 40")
    assert sysrep.version == "1.2"
    assert load_sysrep(FIXTURES / "valid" / "telemetry_only.yaml").commands == ()


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_invalid_sysrep_error_names_file_and_entry(name: str) -> None:
    with pytest.raises(SysRepError) as info:
        load_sysrep(FIXTURES / "invalid" / name)
    message = str(info.value)
    assert "\n" not in message
    for fragment in EXPECTED[name]:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def test_every_invalid_fixture_has_an_expectation() -> None:
    files = {p.name for p in (FIXTURES / "invalid").glob("*.yaml")} - {"expected_errors.yaml"}
    assert files == set(EXPECTED)


def test_missing_file_is_reported(tmp_path: Path) -> None:
    with pytest.raises(SysRepError, match=r"nope\.yaml: cannot read"):
        load_sysrep(tmp_path / "nope.yaml")


def test_duplicate_sysrep_ids_in_a_folder(tmp_path: Path) -> None:
    for name in ("a.yaml", "b.yaml"):
        (tmp_path / name).write_text("id: same\nname: Same\n")
    with pytest.raises(SysRepError, match="duplicate SysRep id 'same'"):
        load_sysrep_dir(tmp_path)


@pytest.mark.parametrize(
    ("type_name", "value", "expected"),
    [
        ("integer", "3", 3),
        ("integer", 4.0, 4),
        ("real", "2.5", 2.5),
        ("real", 1, 1.0),
        ("boolean", "TRUE", True),
        ("boolean", False, False),
        ("string", "x", "x"),
    ],
)
def test_check_value_converts(type_name: str, value: object, expected: object) -> None:
    assert check_value("v", type_name, value) == expected


@pytest.mark.parametrize(
    ("type_name", "value", "problem"),
    [
        ("integer", True, "expected integer"),
        ("integer", 2.5, "expected integer"),
        ("integer", "x", "expected integer"),
        ("real", True, "expected real"),
        ("real", "abc", "expected real"),
        ("boolean", "yes", "expected boolean"),
        ("string", 3, "expected string"),
        ("vector", 1, "unknown type"),
    ],
)
def test_check_value_rejects(type_name: str, value: object, problem: str) -> None:
    with pytest.raises(ValueError, match=problem):
        check_value("v", type_name, value)


def test_check_value_limits() -> None:
    assert check_value("x", "real", 1.0, -2.0, 2.0) == 1.0
    with pytest.raises(ValueError, match="above the maximum"):
        check_value("x", "real", 3.0, -2.0, 2.0)
    with pytest.raises(ValueError, match="below the minimum"):
        check_value("x", "integer", -3, -2, 2)
    with pytest.raises(ValueError, match="not one of"):
        check_value("m", "string", "medium", enum=("fast", "slow"))
