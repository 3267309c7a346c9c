"""Deployment files: one YAML naming a robot side, so starting any robot is ``caretaker up FILE``.

A deployment names the scene, the robot config, the template library, the ROS domain and
namespace, the rosbridge server's address, port and TLS/auth files, the capture and state
folders, and the bindings this robot side serves (and, for ``caretaker demo``, the procedure to
run). Every path in it is relative to the deployment file, and a bare name names a shipped file
(``scene: iva``, ``robot: ur10``, ``bindings: [iva]``); every key is checked (unknown keys
are errors) with the shared :mod:`datafile` reader, and the files it names are checked too, so a
deployment that passes ``caretaker check`` starts. ``ledger`` sets the habitat's command ledger
(always started; its memory lives in the state folder), ``link`` puts an emulated link in front
of the bridge (a rehearsal on one host: ground clients connect to ``link.listen``), ``onboard:
true`` starts the onboard executive (``caretaker onboard``: units from the ground run next to the
robot, with the deployment's bindings; its store lives in the state folder). ``simulator: true``
says the robot side is a simulation, where a draft procedure may run as a rehearsal;
``critical_commanding`` which commands need a second operator's approval (:mod:`pride.approvals`;
the ground reads both through :mod:`pride.robot_sides`). ``displace: SEED`` builds the simulated
world with its slot bodies and targets moved by a seeded offset that only perception finds
(``sim.displacement``; ``caretaker up --displace`` overrides it for one run).

Example (``deployments/iva.yaml``)::

    name: iva
    scene: ../sim/scenes/iva.yaml
    robot: ../python/at_ros/library/robots/ur10.yaml
    templates: ../python/at_ros/library/templates
    bridge: {address: 127.0.0.1, port: 9090}
    bindings: [../sysrep/bindings/iva.yaml]
    demo:
      procedure: ../procedures/iva_cdra_filter_replacement.xml
      binding: ../sysrep/bindings/iva.yaml
      inputs: {clean_filter_id: CDRA-F-0012}
      checks:                           # what must hold of the world afterwards (caretaker.world_checks)
        - {object: filter/CDRA-F-0007, at: rack/slot_3, within_mm: 30}
        - {topic: cdra/installed_filter_id, equals: "${clean_filter_id}"}
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlparse

from at_ros.library import load_library
from at_ros.robot_config import RobotConfig, load_robot_config, load_robot_configs
from caretaker.world_checks import WorldCheck, check_against_scene, load_checks
from datafile import DataFileError, Field, load_file, shipped_or_path
from pride.approvals import ApprovalPolicy, policy_from
from pride.robot_sides import simulator_flag
from procedure_language.binding import Binding, read_binding
from sim.scene import SCENES_DIR, Scene, load_scene

__all__ = [
    "BridgeSettings",
    "DemoRun",
    "Deployment",
    "DeploymentError",
    "LedgerSettings",
    "LinkEmulation",
    "SHIPPED",
    "load_deployment",
    "resolve_deployment",
]

#: The deployments that ship with Caretaker: ``caretaker up iva`` means this folder's iva.yaml.
SHIPPED = Path(__file__).resolve().parents[2] / "deployments"
#: Where the bare names a deployment may use for shipped files are looked up (`scene: iva`).
ROBOTS = Path(__file__).resolve().parents[1] / "at_ros" / "library" / "robots"
BINDINGS = Path(__file__).resolve().parents[2] / "sysrep" / "bindings"
TOP_LEVEL_KEYS = (
    "name",
    "scene",
    "robot",
    "templates",
    "robots",
    "ros",
    "bridge",
    "capture_dir",
    "state_dir",
    "time_scale",
    "bindings",
    "demo",
    "link",
    "ledger",
    "onboard",
    "simulator",
    "critical_commanding",
    "displace",
    "description",
)


class DeploymentError(DataFileError):
    """A deployment file that cannot be started."""


@dataclass(frozen=True)
class BridgeSettings:
    """The robot side's rosbridge server: what ``caretaker bridge`` is started with."""

    address: str = "127.0.0.1"
    port: int = 9090
    certfile: Path | None = None
    keyfile: Path | None = None
    auth_secret_file: Path | None = None

    @property
    def scheme(self) -> str:
        return "wss" if self.certfile else "ws"


@dataclass(frozen=True)
class LedgerSettings:
    """The habitat's command ledger (``caretaker ledger``): every command key executed at most once."""

    retain_hours: float = 168.0  # finished records kept this long (a week)
    default_timeout: float = 10.0  # s a call may take when its request names no timeout


@dataclass(frozen=True)
class LinkEmulation:
    """``caretaker link`` in front of the bridge: what the ground meets on one host (a rehearsal)."""

    listen: tuple[str, int]  # where ground clients connect (port 0: a free one)
    delay: float = 0.0  # s one way
    jitter: float = 0.0
    loss: float = 0.0
    up_kbps: float | None = None
    down_kbps: float | None = None
    seed: int = 0

    def options(self) -> list[str]:
        """The ``caretaker link`` options of this emulation (but --listen, --to and --control)."""
        options = [
            "--delay",
            str(self.delay),
            "--jitter",
            str(self.jitter),
            "--loss",
            str(self.loss),
            "--seed",
            str(self.seed),
        ]
        for option, value in (("--up-kbps", self.up_kbps), ("--down-kbps", self.down_kbps)):
            if value is not None:
                options += [option, str(value)]
        return options


@dataclass(frozen=True)
class DemoRun:
    """What ``caretaker demo`` runs on this robot side, and what it checks of the world (none: the
    run's own outcome only)."""

    procedure: Path
    binding: Path
    inputs: dict[str, str]
    checks: tuple[WorldCheck, ...] = ()


@dataclass(frozen=True)
class Deployment:
    path: Path
    name: str
    scene: Path
    robot: Path  # the robot config file
    robot_name: str
    templates: Path
    robots: Path | None  # folder of robot configs get_robots lists (None: the robot's own config)
    domain_id: int | None  # None: the environment's ROS_DOMAIN_ID
    namespace: str
    bridge: BridgeSettings
    capture_dir: Path | None  # None: the simulation's default ($TMPDIR/caretaker-captures)
    state_dir: Path | None  # None: a new folder per stack (a new stack is a new world)
    time_scale: float
    bindings: tuple[Path, ...]
    demo: DemoRun | None
    link: LinkEmulation | None = None  # None: ground clients reach the bridge itself
    ledger: LedgerSettings = field(default_factory=LedgerSettings)
    onboard: bool = False  # run the onboard executive (needs bindings, and a secret on the bridge)
    simulator: bool = False  # a simulation: drafts may run on it as rehearsals
    approvals: ApprovalPolicy = field(default_factory=lambda: policy_from(None))  # critical commanding
    displace: int | None = None  # a displaced world's seed (sim --displace); None: the scene as drawn


def resolve_deployment(name_or_path: str | Path) -> Path:
    """A deployment file path, or a shipped deployment by name (``iva`` is deployments/iva.yaml).

    Raises:
        DeploymentError: a bare name that is not shipped.
    """
    return shipped_or_path(name_or_path, SHIPPED, "deployment", DeploymentError)


def _bridge(f: Field | None) -> BridgeSettings:
    if f is None:
        return BridgeSettings()
    f.mapping(optional=("address", "port", "certfile", "keyfile", "auth_secret_file"))
    files = {key: f[key].file_path() if f.has(key) else None for key in ("certfile", "keyfile", "auth_secret_file")}
    if (files["certfile"] is None) != (files["keyfile"] is None):
        raise f.fail("certfile and keyfile go together (TLS needs both)")
    return BridgeSettings(
        address=f["address"].text() if f.has("address") else "127.0.0.1",
        port=f["port"].integer(min=0, max=65535) if f.has("port") else 9090,
        **files,
    )


def _demo(f: Field | None) -> DemoRun | None:
    if f is None:
        return None
    f.mapping(required=("procedure", "binding"), optional=("inputs", "checks"))
    inputs = {}
    for key, value in f["inputs"].entries() if f.has("inputs") else []:
        if value.node.kind != "scalar" or value.node.value is None:
            raise value.fail(f"the answer to record {key!r} must be a single value, got {value.describe()}")
        inputs[key] = str(value.node.value).lower() if isinstance(value.node.value, bool) else str(value.node.value)
    return DemoRun(
        procedure=f["procedure"].file_path(),
        binding=f["binding"].file_path(shipped=BINDINGS, what="binding"),
        inputs=inputs,
        checks=load_checks(f["checks"], inputs) if f.has("checks") else (),
    )


def _ledger(f: Field | None) -> LedgerSettings:
    if f is None:
        return LedgerSettings()
    f.mapping(optional=("retain_hours", "default_timeout"))
    defaults = LedgerSettings()
    return LedgerSettings(
        retain_hours=f["retain_hours"].number(min=0.01) if f.has("retain_hours") else defaults.retain_hours,
        default_timeout=f["default_timeout"].number(min=0.01) if f.has("default_timeout") else defaults.default_timeout,
    )


def _address(f: Field) -> tuple[str, int]:
    text = f.text()
    host, colon, port = text.rpartition(":")
    if not colon or not host or not port.isdigit() or int(port) > 65535:
        raise f.fail(f"{text!r} is not HOST:PORT, e.g. 127.0.0.1:9091")
    return host.strip("[]"), int(port)


def _link(f: Field | None) -> LinkEmulation | None:
    if f is None:
        return None
    f.mapping(required=("listen",), optional=("delay", "jitter", "loss", "up_kbps", "down_kbps", "seed"))
    return LinkEmulation(
        listen=_address(f["listen"]),
        delay=f["delay"].number(min=0.0, max=3600.0) if f.has("delay") else 0.0,
        jitter=f["jitter"].number(min=0.0, max=3600.0) if f.has("jitter") else 0.0,
        loss=_loss(f["loss"]) if f.has("loss") else 0.0,
        up_kbps=f["up_kbps"].number(min=0.001) if f.has("up_kbps") else None,
        down_kbps=f["down_kbps"].number(min=0.001) if f.has("down_kbps") else None,
        seed=f["seed"].integer(min=0) if f.has("seed") else 0,
    )


def _loss(f: Field) -> float:
    loss = f.number(min=0.0)
    if loss >= 1:
        raise f.fail(f"expected a fraction >= 0 and < 1 (0.05 is 5 %), got {loss:g}")
    return loss


def load_deployment(path: str | Path, *, check_files: bool = True) -> Deployment:
    """Read a deployment file; with ``check_files`` also every file it names, and that they agree.

    Raises:
        DeploymentError: ``file:line: key: problem`` for the deployment itself or a disagreement.
        DataFileError: for a file it names (scene, robot config, template, binding, SysRep).
    """
    path = resolve_deployment(path)
    root = load_file(path, error=DeploymentError).mapping(
        required=("name", "scene", "robot", "templates"), optional=TOP_LEVEL_KEYS
    )
    ros = root.get("ros")
    if ros is not None:
        ros.mapping(optional=("domain_id", "namespace"))
    namespace = ros["namespace"].text(empty=True) if ros is not None and ros.has("namespace") else ""
    if namespace and not namespace.startswith("/"):
        raise ros["namespace"].fail(f"a namespace starts with '/', e.g. /{namespace}")  # type: ignore[index]
    robot_file = root["robot"].file_path(shipped=ROBOTS, what="robot config")
    robot = load_robot_config(robot_file)
    deployment = Deployment(
        path=path,
        name=root["name"].text(),
        scene=root["scene"].file_path(shipped=SCENES_DIR, what="scene"),
        robot=robot_file,
        robot_name=robot.robot_name,
        templates=root["templates"].file_path(folder=True),
        robots=root["robots"].file_path(folder=True) if root.has("robots") else None,
        domain_id=ros["domain_id"].integer(min=0, max=232) if ros is not None and ros.has("domain_id") else None,
        namespace=namespace,
        bridge=_bridge(root.get("bridge")),
        capture_dir=root["capture_dir"].file_path(folder=True, must_exist=False) if root.has("capture_dir") else None,
        state_dir=root["state_dir"].file_path(folder=True, must_exist=False) if root.has("state_dir") else None,
        time_scale=root["time_scale"].number(min=0.0, max=1000.0) if root.has("time_scale") else 1.0,
        bindings=tuple(b.file_path(shipped=BINDINGS, what="binding") for b in root["bindings"].sequence())
        if root.has("bindings")
        else (),
        demo=_demo(root.get("demo")),
        link=_link(root.get("link")),
        ledger=_ledger(root.get("ledger")),
        onboard=root["onboard"].boolean() if root.has("onboard") else False,
        simulator=simulator_flag(root.get("simulator")),
        approvals=policy_from(root.get("critical_commanding")),
        displace=root["displace"].integer(min=0) if root.has("displace") else None,
    )
    if deployment.onboard and not deployment.bindings:
        raise root["onboard"].fail("the onboard executive runs units with this deployment's bindings: list them")
    if deployment.onboard and deployment.bridge.auth_secret_file is None:
        raise root["onboard"].fail(
            "the onboard executive takes only units signed with the link's secret: give bridge.auth_secret_file"
        )
    if check_files:
        _check_files(root, deployment, robot)
    return deployment


def _check_files(root: Field, deployment: Deployment, robot: RobotConfig) -> None:
    """Every file the deployment names loads, and they describe one robot side."""
    scene = load_scene(deployment.scene)
    _check_robot_matches_scene(root, robot, scene)
    load_library(deployment.templates)
    if deployment.robots is not None:
        load_robot_configs(deployment.robots)
    for index, binding_path in enumerate(deployment.bindings):
        _check_binding_reaches_this_side(root["bindings"].sequence()[index], read_binding(binding_path), deployment)
    if deployment.demo is not None:
        demo = root["demo"]
        if deployment.demo.binding not in deployment.bindings:
            raise demo["binding"].fail("the demo's binding is not one of this deployment's bindings")
        if deployment.demo.checks:
            check_against_scene(demo["checks"], deployment.demo.checks, scene)


def _check_robot_matches_scene(root: Field, robot: RobotConfig, scene: Scene) -> None:
    if os.path.realpath(robot.urdf) != os.path.realpath(scene.robot.urdf):
        raise root["robot"].fail(
            f"robot config {robot.filename} uses model {robot.urdf}, but scene {scene.path} has {scene.robot.urdf}"
        )
    missing = [j for j in robot.joint_names if j not in scene.robot.arm_joints]
    if missing:
        raise root["robot"].fail(
            f"robot config joints {missing} are not arm joints of scene {scene.path} "
            f"({', '.join(scene.robot.arm_joints)})"
        )
    if robot.gripper_service and scene.robot.gripper is None:
        raise root["robot"].fail(
            f"robot config names gripper_service {robot.gripper_service!r}, "
            f"but the robot of scene {scene.path} has no gripper"
        )


def _check_binding_reaches_this_side(f: Field, binding: Binding, deployment: Deployment) -> None:
    """A binding this side serves must connect to its rosbridge and name its namespace."""
    for system in binding.systems:
        url = urlparse(system.rosbridge)
        if url.port != deployment.bridge.port and deployment.bridge.port != 0:
            raise f.fail(
                f"binding {binding.path} connects {system.sysrep} to {system.rosbridge}, "
                f"but this deployment's rosbridge port is {deployment.bridge.port}"
            )
        if url.scheme != deployment.bridge.scheme:
            raise f.fail(
                f"binding {binding.path} connects {system.sysrep} with {url.scheme}://, "
                f"but this deployment's rosbridge serves {deployment.bridge.scheme}://"
            )
        if deployment.namespace and not system.namespace.startswith(deployment.namespace + "/"):
            raise f.fail(
                f"binding {binding.path} serves {system.sysrep} on {system.namespace or '/'}, "
                f"outside this deployment's namespace {deployment.namespace}"
            )
    if binding.ledger_namespace != deployment.namespace:
        # The stack puts the command ledger in the deployment's namespace, so that robots sharing a
        # ROS graph never share a ledger (two ledgers on one name would both execute a command).
        raise f.fail(
            f"binding {binding.path} looks for the command ledger in {binding.ledger_namespace or '/'}, but this "
            f"deployment's ledger is in {deployment.namespace or '/'} (set ledger_namespace: "
            f"{deployment.namespace or '/'} in the binding)"
        )
