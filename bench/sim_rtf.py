"""Real-time factor of the simulator at as-fast-as-possible, per scene.

Usage: .venv/bin/python bench/sim_rtf.py [--seconds 20]

For each scene it runs, in one process and side by side:
  * bare pybullet: ``stepSimulation`` on the same world (the engine's floor, no robot logic);
  * ``Simulation.step`` idle (nothing commanded);
  * ``Simulation.step`` executing a joint trajectory (kinematic arm, held-object and collision
    checks every step), which is what ``--time-scale 0`` runs while the robot moves.
RTF = simulated seconds / wall seconds. The ratio column is our step's cost relative to bare
pybullet (how much the robot logic slows the engine down). ROS publishing is not included there;
the last rows run the real node (``caretaker sim --time-scale 0``, its own process) and time a
trajectory sent through the action from send to result: RTF with ROS publishing included.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from collections.abc import Callable
from functools import partial
from typing import Any

import pybullet as p

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from sim.scene import load_scene
from sim.simulation import Simulation
from sim.trajectory import validate_trajectory


def rtf(step: Callable[[], object], dt: float, seconds: float) -> float:
    steps = int(seconds / dt)
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return steps * dt / (time.perf_counter() - start)


def moving_rtf(sim: Simulation, seconds: float) -> float:
    """Sweep the first two arm joints back and forth, 2 s per sweep, for ``seconds`` of sim time."""
    start = time.perf_counter()
    simulated = 0.0
    sign = 1.0
    while simulated < seconds:
        current = tuple(sim.arm_positions)
        goal = list(current)
        goal[0] += sign * 0.4
        goal[1] += sign * 0.1
        sign = -sign
        traj = validate_trajectory(
            list(sim.arm_joints),
            [(2.0, goal, [])],
            limits=sim.limits,
            controller_joints=sim.arm_joints,
            current=current,
        )
        run = sim.start_trajectory(traj, 0.0)
        while not run.done.is_set():
            sim.step()
            simulated += sim.dt
        if run.error_code != 0:
            raise RuntimeError(f"benchmark trajectory failed: {run.error_string}")
    return simulated / (time.perf_counter() - start)


def node_rtf(scene: str, seconds: float) -> float:
    """Sim seconds per wall second of the node executing one ``seconds``-long trajectory."""
    import rclpy
    from builtin_interfaces.msg import Duration
    from caretaker_sim_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor
    from trajectory_msgs.msg import JointTrajectoryPoint

    from caretaker.processes import caretaker

    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(150 + os.getpid() % 80))
    os.environ.update(env)
    proc = caretaker("sim", "--scene", scene, "--time-scale", "0", "--camera-period", "0", env=env)
    rclpy.init()
    node = rclpy.create_node("sim_rtf_bench")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    try:
        proc.wait_ready(90.0)
        spinner.start()
        sim = Simulation(load_scene(scene))  # only for joint names and start positions
        names, start = list(sim.arm_joints), list(sim.arm_positions)
        sim.close()
        client = ActionClient(node, FollowJointTrajectory, "/arm_controller/follow_joint_trajectory")
        if not client.wait_for_server(timeout_sec=60):
            raise RuntimeError("action server not available")
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = names
        for k in range(1, int(seconds) + 1):  # sweep the first joint ±0.1 rad, one point per second
            pt = JointTrajectoryPoint()
            pt.positions = [start[0] + (0.1 if k % 2 else -0.1)] + start[1:]
            pt.time_from_start = Duration(sec=k)
            goal.trajectory.points.append(pt)
        done = threading.Event()
        results: list = []

        def on_result(future: Any) -> None:  # an rclpy Future of the goal's result
            results.append(future.result().result)
            done.set()

        began = time.perf_counter()
        # On the executor thread: rclpy 7.1's ActionClient drops a response that beats the
        # bookkeeping of a request sent from another thread.
        executor.create_task(
            lambda: client.send_goal_async(goal).add_done_callback(
                lambda f: f.result().get_result_async().add_done_callback(on_result)
            )
        )
        if not done.wait(600):
            raise RuntimeError("no result")
        wall = time.perf_counter() - began
        if results[0].error_code != 0:
            raise RuntimeError(f"benchmark trajectory failed: {results[0].error_string}")
        return int(seconds) / wall
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        proc.stop()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per measurement")
    args = parser.parse_args(argv)
    print(f"{'scene':6} {'case':22} {'RTF':>8} {'step µs':>9} {'vs bare':>8}")
    for name in ("iva", "eva"):
        sim = Simulation(load_scene(name), seed=0)
        client = sim.client
        bare = rtf(partial(p.stepSimulation, physicsClientId=client), sim.dt, args.seconds)
        idle = rtf(sim.step, sim.dt, args.seconds)
        moving = moving_rtf(sim, args.seconds)
        for case, value in (("bare pybullet step", bare), ("Simulation idle", idle), ("Simulation arm moving", moving)):
            print(f"{name:6} {case:22} {value:8.1f} {sim.dt / value * 1e6:9.1f} {bare / value:7.2f}x")
        sim.close()
    for name in ("iva", "eva"):
        value = node_rtf(name, args.seconds)
        print(f"{name:6} {'node (ROS), arm moving':22} {value:8.1f} {1e6 / 240 / value:9.1f} {'':>8}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
