"""Deployment files and the command lines built from them: checked before anything starts.

A deployment names a robot side (scene, robot config, templates, bindings, rosbridge settings,
folders); its paths are relative to the file; every mistake is one line with file:line: key;
the stack's parts are data (caretaker.stack.PARTS) and their command lines carry what the
deployment says, the bridge's TLS and auth files included. Unknown options are errors for
every part.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from at_ros.command_line import add_robot_options, choose_robot
from at_ros.library import LibraryError, default_library_path
from caretaker.deployment import SHIPPED, DeploymentError, load_deployment
from caretaker.stack import PARTS, Stack, StackFailed
from datafile import DataFileError
from support.stack import write_deployment

REPO = Path(__file__).resolve().parents[2]


def _caretaker(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


def test_the_shipped_deployments_load_with_every_file_they_name() -> None:
    for name in ("iva", "eva"):
        deployment = load_deployment(name)
        assert deployment.path == SHIPPED / f"{name}.yaml"
        assert deployment.scene == REPO / "sim" / "scenes" / f"{name}.yaml"  # relative to the deployment file
        assert deployment.demo is not None and deployment.demo.checks  # the demo checks the world
    assert load_deployment("eva").bridge.port == 9091


@pytest.mark.parametrize(
    ("changes", "key", "problem"),
    [
        ({"scen": "x.yaml"}, "scen", "unknown key 'scen'"),
        ({"scene": "nowhere.yaml"}, "scene", "no such file"),
        ({"templates": None}, "templates", "missing required key"),
        ({"bridge": {"port": 70000}}, "bridge.port", "above the maximum 65535"),
        ({"bridge": {"port": 9090, "certfile": "/etc/hostname"}}, "bridge", "certfile and keyfile go together"),
        ({"bridge": {"port": 9091}}, "bindings[0]", "this deployment's rosbridge port is 9091"),
        ({"ros": {"namespace": "/arm2"}}, "bindings[0]", "outside this deployment's namespace /arm2"),
        ({"ros": {"namespace": "arm2"}}, "ros.namespace", "starts with '/'"),
        ({"ros": {"domain_id": "seven"}}, "ros.domain_id", "expected an integer"),
        (
            {
                "demo": {
                    "procedure": str(REPO / "procedures" / "iva_cdra_filter_replacement.xml"),
                    "binding": str(REPO / "sysrep" / "bindings" / "iva.yaml"),
                    "checks": [{"object": "filter/CDRA-F-0007", "at": "rack/slot_9", "within_mm": 30}],
                }
            },
            "demo.checks[0].at",
            "scene iva.yaml has no frame 'rack/slot_9'",
        ),
        ({"scene": str(REPO / "sim" / "scenes" / "eva.yaml")}, "robot", "but scene"),
        ({"link": ["delay"]}, "link", "expected a mapping"),
    ],
)
def test_a_wrong_deployment_is_one_line_naming_file_line_and_key(
    tmp_path: Path, changes: dict, key: str, problem: str
) -> None:
    path = write_deployment(tmp_path, "iva", **changes)
    with pytest.raises(DataFileError) as info:
        load_deployment(path)
    message = str(info.value)
    assert info.value.key == key and problem in message, message
    assert message.startswith(f"{path}:") and "\n" not in message


def test_paths_are_relative_to_the_deployment_file(tmp_path: Path) -> None:
    folder = tmp_path / "site"
    folder.mkdir()
    (folder / "templates").mkdir()
    (folder / "templates" / "ready.json").write_text(
        (default_library_path() / "templates" / "ready_pose.json").read_text()
    )
    path = write_deployment(folder, "iva", templates="templates", capture_dir="captures", state_dir="state")
    deployment = load_deployment(path)
    assert deployment.templates == folder / "templates"
    assert deployment.capture_dir == folder / "captures" and deployment.state_dir == folder / "state"


def test_the_stack_command_lines_carry_the_deployment(tmp_path: Path) -> None:
    secret, cert, key = (tmp_path / name for name in ("secret", "cert.pem", "key.pem"))
    for path in (secret, cert, key):
        path.write_text("x")
    binding = yaml.safe_load((REPO / "sysrep" / "bindings" / "iva.yaml").read_text())
    binding["rosbridge"] = "wss://127.0.0.1:9443"
    binding["systems"] = [dict(s, sysrep=str(REPO / "sysrep" / Path(s["sysrep"]).name)) for s in binding["systems"]]
    (tmp_path / "binding.yaml").write_text(yaml.safe_dump(binding))
    path = write_deployment(
        tmp_path,
        "iva",
        bridge={
            "address": "127.0.0.1",
            "port": 9443,
            "certfile": str(cert),
            "keyfile": str(key),
            "auth_secret_file": str(secret),
        },
        bindings=[str(tmp_path / "binding.yaml")],
        demo=None,
        ros={"namespace": "/iva", "domain_id": 42},
        capture_dir=str(tmp_path / "captures"),
        onboard=True,
        displace=7,
    )
    deployment = load_deployment(path, check_files=False)
    stack = Stack(deployment, time_scale=0.0, env={}, cabin={"cabin_start_ppco2": 3.95, "cabin_chemistry_scale": 30})
    try:
        lines = {part.name: part.command(deployment, stack.run) for part in stack.parts}
    finally:
        stack.stop()
    assert (
        [p.name for p in PARTS if p.name != "link"]
        == list(lines)
        == ["sim", "perception", "planner", "at-server", "ledger", "bridge", "onboard"]
    )
    assert lines["onboard"] == [
        "onboard",
        "--bridge",
        "wss://127.0.0.1:9443",
        "--state-dir",
        str(stack.run.state_dir / "onboard"),
        "--binding",
        str(tmp_path / "binding.yaml"),
    ]
    assert lines["ledger"][:3] == ["ledger", "--state-dir", str(stack.run.state_dir / "ledger")]
    assert lines["bridge"] == [
        "bridge",
        "--address",
        "127.0.0.1",
        "--port",
        "9443",
        "--ready-services",
        "*/halt",
        "--certfile",
        str(cert),
        "--keyfile",
        str(key),
        "--auth-secret-file",
        str(secret),
    ]
    assert lines["sim"][:4] == ["sim", "--scene", str(deployment.scene), "--time-scale"] and "/iva" in lines["sim"]
    assert lines["sim"][-8:] == [
        "--capture-dir",
        str(tmp_path / "captures"),
        "--displace",
        "7",
        "--cabin-start-ppco2",
        "3.95",
        "--cabin-chemistry-scale",
        "30.0",
    ]
    assert lines["perception"] == ["perception", "--namespace", "/iva"]
    for part in ("planner", "at-server"):
        assert lines[part][1:5] == ["--robot", str(deployment.robot), "--templates", str(deployment.templates)]
        assert lines[part][lines[part].index("--namespace") :][:2] == ["--namespace", "/iva"]
    assert lines["at-server"][-2] == "--state-file"
    assert lines["ledger"][7:] == [
        "--ros-args",
        "-r",
        "__ns:=/iva",
        "-r",
        "/command_ledger/execute:=/iva/command_ledger/execute",
        "-r",
        "/command_ledger/outcome:=/iva/command_ledger/outcome",
    ]
    assert stack.env["ROS_DOMAIN_ID"] == "42"
    assert stack.bridge_url == "wss://127.0.0.1:9443"
    with pytest.raises(StackFailed, match="unknown parts"):
        Stack(deployment, parts=["sim", "ledgr"], env={})


def test_a_link_section_puts_an_emulated_link_in_front_of_the_bridge(tmp_path: Path) -> None:
    path = write_deployment(
        tmp_path,
        "iva",
        link={"listen": "127.0.0.1:0", "delay": 1.3, "loss": 0.05, "down_kbps": 64, "up_kbps": 16, "seed": 7},
        ledger={"retain_hours": 24},
        bridge={"address": "127.0.0.1", "port": 9090},
    )
    deployment = load_deployment(path, check_files=False)
    stack = Stack(deployment, time_scale=0.0, env={})
    try:
        lines = {part.name: part.command(deployment, stack.run) for part in stack.parts}
        assert list(lines)[-2:] == ["bridge", "link"]
        link = lines["link"]
        assert link[:7] == [
            "link",
            "--listen",
            "127.0.0.1:0",
            "--to",
            "127.0.0.1:9090",
            "--control",
            str(stack.run.state_dir / "link.sock"),
        ]
        options = dict(zip(link[7::2], link[8::2], strict=True))
        assert options == {
            "--delay": "1.3",
            "--jitter": "0.0",
            "--loss": "0.05",
            "--seed": "7",
            "--up-kbps": "16.0",
            "--down-kbps": "64.0",
        }
        assert lines["ledger"][3:] == ["--retain-hours", "24.0", "--default-timeout", "10.0"]
        stack.run.link_port = 40000
        assert stack.url == "ws://127.0.0.1:40000" and stack.bridge_url == "ws://127.0.0.1:9090"
    finally:
        stack.stop()
    for bad, problem in (
        ({"listen": "nowhere"}, "is not HOST:PORT"),
        ({"listen": "h:1", "loss": 1.5}, "fraction"),
        ({"listen": "h:1", "dealy": 1}, "unknown key 'dealy'"),
    ):
        with pytest.raises(DeploymentError, match=problem):
            load_deployment(write_deployment(tmp_path, "iva", link=bad), check_files=False)


def test_robots_sharing_a_ros_graph_never_share_a_command_ledger(tmp_path: Path) -> None:
    binding = yaml.safe_load((REPO / "sysrep" / "bindings" / "iva.yaml").read_text())
    binding["systems"] = [
        dict(s, sysrep=str(REPO / "sysrep" / Path(s["sysrep"]).name), namespace="/arm2" + s["namespace"])
        for s in binding["systems"]
    ]
    (tmp_path / "binding.yaml").write_text(yaml.safe_dump(binding))
    path = write_deployment(
        tmp_path, "iva", ros={"namespace": "/arm2"}, bindings=[str(tmp_path / "binding.yaml")], demo=None
    )
    with pytest.raises(
        DeploymentError,
        match=r"looks for the command ledger in /, but this deployment's ledger is in "
        r"/arm2 \(set ledger_namespace: /arm2 in the binding\)",
    ):
        load_deployment(path)
    binding["ledger_namespace"] = "/arm2"
    (tmp_path / "binding.yaml").write_text(yaml.safe_dump(binding))
    assert load_deployment(path).namespace == "/arm2"


@pytest.mark.parametrize(
    "argv",
    [
        ["planner", "--robot", "ur10", "--bogus"],
        ["at-server", "--robot", "ur10", "--bogus"],
        ["sim", "--scene", "iva", "--bogus"],
        ["up", "iva", "--bogus"],
        ["demo", "iva", "--bogus"],
        ["check", "--bogus", "x.yaml"],
    ],
)
def test_an_unknown_option_is_an_error_for_every_part(argv: list[str]) -> None:
    proc = _caretaker(*argv)
    assert proc.returncode == 2 and "unrecognized arguments: --bogus" in proc.stderr, proc.stderr


def test_a_cabin_knob_out_of_range_is_refused_before_anything_starts() -> None:
    proc = _caretaker("up", "iva", "--cabin-chemistry-scale", "nan")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines()[-1] == (
        "caretaker up: error: argument --cabin-chemistry-scale: cabin_chemistry_scale must be a number > 0 and "
        "<= 3600, got nan"
    )


def test_caretaker_up_refuses_a_broken_deployment_before_starting_anything(tmp_path: Path) -> None:
    path = write_deployment(tmp_path, "iva", scene="nowhere.yaml")
    proc = _caretaker("up", str(path))
    assert proc.returncode == 1
    assert (
        proc.stderr.strip() == f"caretaker up: {path}:2: scene: no such file: {tmp_path / 'nowhere.yaml'} "
        f"('nowhere.yaml' relative to {tmp_path})"
    )
    assert _caretaker("up", "moon").stderr.startswith(
        "caretaker up: moon: no such deployment; give a deployment file or one of eva, iva"
    )


def _robot_args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_robot_options(parser)
    return parser.parse_args(argv)


def test_a_library_of_templates_only_needs_no_robots_folder(tmp_path: Path) -> None:
    (tmp_path / "templates").mkdir()
    choice = choose_robot(_robot_args("--robot", "ur10", "--library", str(tmp_path)))
    assert choice.robot.robot_name == "ur10" and choice.templates == tmp_path / "templates"
    assert set(choice.robots) >= {"ur10", "eva_arm"}  # the shipped robots
    robot_file = default_library_path() / "robots" / "eva_arm.yaml"
    alone = choose_robot(_robot_args("--robot", str(robot_file)))
    assert alone.robot.robot_name == "eva_arm" and list(alone.robots) == ["eva_arm"]
    with pytest.raises(LibraryError, match="unknown robot 'r2d2'; known: eva_arm, ur10"):
        choose_robot(_robot_args("--robot", "r2d2"))
    with pytest.raises(DeploymentError, match="no such deployment"):
        load_deployment("r2d2")


@pytest.mark.parametrize(
    ("given", "said"),
    [
        ({"bindings": []}, "the onboard executive runs units with this deployment's bindings: list them"),
        ({"bridge": {"address": "127.0.0.1", "port": 0}}, "give bridge.auth_secret_file"),
    ],
)
def test_an_onboard_executive_needs_bindings_and_the_links_secret(
    tmp_path: Path, given: dict[str, object], said: str
) -> None:
    secret = tmp_path / "secret"
    secret.write_text("x")
    options: dict[str, object] = {
        "bridge": {"address": "127.0.0.1", "port": 0, "auth_secret_file": str(secret)},
        "bindings": [str(REPO / "sysrep" / "bindings" / "iva.yaml")],
        "onboard": True,
        **given,
    }
    with pytest.raises(DeploymentError) as refused:
        load_deployment(write_deployment(tmp_path, "iva", **options), check_files=False)
    assert said in str(refused.value) and str(refused.value).startswith(str(tmp_path / "iva.yaml")), refused.value


def test_a_deployment_outside_the_checkout_names_shipped_files_by_name(tmp_path: Path) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text(
        "name: mine\nscene: iva\nrobot: ur10\n"
        f"templates: {default_library_path() / 'templates'}\n"
        "bindings: [iva]\n"
        "demo: {procedure: %s, binding: iva}\n" % (REPO / "procedures" / "iva_cdra_filter_replacement.xml")
    )
    deployment = load_deployment(path)
    assert deployment.scene == REPO / "sim" / "scenes" / "iva.yaml"
    assert deployment.robot == default_library_path() / "robots" / "ur10.yaml"
    assert deployment.bindings == (REPO / "sysrep" / "bindings" / "iva.yaml",)
    assert deployment.demo is not None and deployment.demo.binding == deployment.bindings[0]


def test_an_unknown_shipped_name_is_refused_at_its_line_with_the_names_there_are(tmp_path: Path) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text(f"name: mine\nscene: iva\nrobot: ur11\ntemplates: {default_library_path() / 'templates'}\n")
    with pytest.raises(
        DeploymentError, match=r"mine\.yaml:3: robot: no shipped robot config named 'ur11'; .*eva_arm, ur10"
    ):
        load_deployment(path)


def test_the_demo_keeps_its_log_beside_a_deployment_outside_the_checkout(tmp_path: Path) -> None:
    from caretaker.demo import demo_home

    assert demo_home(load_deployment("iva")) == REPO / "var"  # where `caretaker report` looks from the checkout
    outside = load_deployment(write_deployment(tmp_path, "iva"), check_files=False)
    assert demo_home(outside) == tmp_path / "var"
