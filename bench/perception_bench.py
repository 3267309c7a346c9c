"""Perception benchmark: detection time per 640x480 image, and location error against distance and angle.

The IVA scene is displaced (``--displace`` seed) and given fixed cameras around the cabinet slot
and a rack slot (markers 10 cm, two per object 25-30 cm apart) and square-on to a seated filter
(3.6 cm markers beside its handle): every distance and angle of the grid. Each camera's image is
rendered by the simulation's own code (pybullet TinyRenderer, 640x480, 45 deg vertical field)
and located by the perception node's own code (``perception.locate``: ArUco detection with
AprilTag corner refinement, joint SQPnP + Levenberg-Marquardt over every corner), in this
process, against the simulator's ground truth (``Simulation.true_frames``). Reported: the time
of ``locate`` per image (wall and CPU of this process; detection is most of it), the time to
render the image for scale, and per (object, distance, angle) the position and rotation errors,
or the refusal.

    .venv/bin/python bench/perception_bench.py
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from at_ros.transforms import angle_between, from_xyz_quat, from_xyz_rpy
from perception.locate import DEFAULT_TOLERANCE_PX, Calibration, MarkerOnObject, NotLocated, locate
from sim.cameras import fixed_camera_pose, intrinsics, render
from sim.displacement import compose, displaced_scene
from sim.scene import SCENES_DIR, Scene, load_scene
from sim.simulation import Simulation


@dataclass(frozen=True)
class Shot:
    obj: str
    distance: float
    angle_deg: float  # about the vertical, from the markers' normal
    camera: str


def _frame(scene: Scene, name: str) -> object:
    if name in scene.slots:
        return scene.slots[name].pose
    spec = next(f for f in scene.filters if f"filter/{f.id}" == name)
    return scene.slots[spec.slot].pose


def _camera(scene: Scene, shot: Shot, elevation_deg: float) -> dict[str, object]:
    """A camera ``shot.distance`` from the middle of the object's markers (where ``scene`` has
    them), turned ``shot.angle_deg`` about the vertical and raised ``elevation_deg``."""
    poses = [compose(_frame(scene, shot.obj), m.pose) for m in scene.markers if m.frame == shot.obj]  # type: ignore[arg-type]
    centre = np.mean([p.xyz for p in poses], axis=0)
    normal = from_xyz_quat(poses[0].xyz, poses[0].quaternion)[:3, 2]
    heading = math.atan2(normal[1], normal[0]) + math.radians(shot.angle_deg)
    el = math.radians(elevation_deg)
    direction = np.array([math.cos(heading) * math.cos(el), math.sin(heading) * math.cos(el), math.sin(el)])
    eye = centre + shot.distance * direction
    return {
        "name": shot.camera,
        "eye": [float(v) for v in eye],
        "target": [float(v) for v in centre],
        "fov_deg": 45,
        "width": 640,
        "height": 480,
        "near": 0.02,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--displace", type=int, default=11, help="seed of the displaced world")
    parser.add_argument("--repeat", type=int, default=5, help="times each image is located (timing)")
    args = parser.parse_args()
    nominal = load_scene("iva")
    displaced = displaced_scene(nominal, args.displace)
    shots = [
        Shot(obj, d, a, f"{obj.replace('/', '_').replace('-', '_')}_{int(d * 100)}_{int(a) + 90}")
        for obj in ("cabinet/slot", "rack/slot_2")
        for d in (0.4, 0.6, 0.8, 1.0, 1.2)
        for a in (0.0, 15.0, 30.0, 45.0)
    ]
    shots += [
        Shot("filter/CDRA-F-0012", d, a, f"filter_{int(d * 100)}_{int(a) + 90}")
        for d in (0.25, 0.3, 0.4, 0.5)
        for a in (0.0, 5.0, 10.0)
    ]
    data = yaml.safe_load((SCENES_DIR / "iva.yaml").read_text())
    data["robot"]["urdf"] = str((SCENES_DIR / data["robot"]["urdf"]).resolve())
    # the slots aimed at where the drawings have them; the filter square-on where it is
    data["cameras"] += [
        _camera(displaced if s.obj.startswith("filter/") else nominal, s, 10.0 if s.obj.startswith("filter/") else 25.0)
        for s in shots
    ]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "iva_bench.yaml"
        path.write_text(yaml.safe_dump(data))
        sim = Simulation(load_scene(path), displace=args.displace)
    truth = dict(sim.true_frames())
    locate_wall, locate_cpu, render_wall = [], [], []
    rows = []
    for shot in shots:
        spec = sim.scene.cameras[shot.camera]
        started = time.perf_counter()
        image = render(spec, sim.client)
        render_wall.append(time.perf_counter() - started)
        gray = cv2.cvtColor(np.frombuffer(image.rgb, np.uint8).reshape(spec.height, spec.width, 3), cv2.COLOR_RGB2GRAY)
        fx, fy, cx, cy = intrinsics(spec)
        calibration = Calibration(spec.width, spec.height, np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]))
        markers = [
            MarkerOnObject(m.id, m.size, from_xyz_rpy(m.pose.xyz, m.pose.rpy))
            for m in sim.scene.markers
            if m.frame == shot.obj
        ]
        outcome = ""
        for _ in range(args.repeat):
            wall, cpu = time.perf_counter(), time.process_time()
            try:
                located = locate(gray, calibration, sim.scene.marker_dictionary, markers, DEFAULT_TOLERANCE_PX)
            except NotLocated as exc:
                outcome = f"refused: {exc}"
            locate_wall.append(time.perf_counter() - wall)
            locate_cpu.append(time.process_time() - cpu)
        if not outcome:
            world = from_xyz_quat(*fixed_camera_pose(spec)) @ located.camera_to_object
            real = from_xyz_quat(*truth[shot.obj])
            mm = float(np.linalg.norm(world[:3, 3] - real[:3, 3]) * 1000)
            deg = math.degrees(angle_between(world, real))
            outcome = f"{mm:.2f} mm, {deg:.2f} deg, {located.residual_px:.2f} px"
        rows.append((shot, outcome))
    sim.close()

    def ms(values: list[float], percent: int) -> str:
        return f"{statistics.quantiles(values, n=100)[percent - 1] * 1000:.1f}"

    print(
        f"{len(shots)} images 640x480, each located {args.repeat} times (displaced world, seed {args.displace}; "
        f"tolerance {DEFAULT_TOLERANCE_PX} px)"
    )
    print(
        f"locate per image: median {statistics.median(locate_wall) * 1000:.1f} ms wall "
        f"({statistics.median(locate_cpu) * 1000:.1f} ms CPU), p95 {ms(locate_wall, 95)} ms, "
        f"max {max(locate_wall) * 1000:.1f} ms"
    )
    print(f"render per image (for scale): median {statistics.median(render_wall) * 1000:.1f} ms")
    print("| object | distance (m) | angle (deg) | error |")
    print("|---|---|---|---|")
    for shot, outcome in rows:
        print(f"| {shot.obj} | {shot.distance:.2f} | {shot.angle_deg:.0f} | {outcome} |")


if __name__ == "__main__":
    main()
