"""Joint-space motion planning with OMPL (RRTConnect) and path shortcutting.

A straight joint-space line is tried first: most moves between nearby waypoints are free, and
checking one line costs a few milliseconds where a solve plus simplification costs tens.
OMPL's solve() holds the GIL, which is why this runs in the planner node's own process.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

__all__ = ["JointPlanner", "PlanningFailed", "segment_is_valid"]


#: Wall-clock length of one OMPL solve call (s): short enough that a starved thread's budget is
#: counted in its own CPU time to within a slice, long enough that a call's set-up is negligible.
SOLVE_SLICE = 0.05

_seeded: list[int] = []  # the seed OMPL's process-wide generator got, once set


class PlanningFailed(RuntimeError):
    """No collision-free joint path was found in the time allowed."""


def segment_is_valid(a: np.ndarray, b: np.ndarray, is_valid: Callable[[np.ndarray], bool], resolution: float) -> bool:
    """Check the straight joint-space line a→b at ``resolution`` rad (max-norm) steps."""
    steps = max(1, int(np.ceil(np.max(np.abs(b - a)) / resolution)))
    return all(is_valid(a + (b - a) * (i / steps)) for i in range(1, steps + 1))


class JointPlanner:
    """Plans collision-free joint paths between two configurations.

    Args:
        lower, upper: joint limits.
        is_valid: the scene's validity check of one configuration.
        resolution: max joint step (rad) between checked states along a motion.
        extension: RRTConnect's range, the longest tree extension (rad).
        seed: OMPL's process-wide random seed, for reproducible plans.
    """

    def __init__(
        self,
        lower: np.ndarray,
        upper: np.ndarray,
        is_valid: Callable[[np.ndarray], bool],
        *,
        resolution: float = 0.03,
        extension: float = 1.0,
        seed: int = 1,
    ) -> None:
        ou.setLogLevel(ou.LOG_WARN)
        if not _seeded:  # OMPL's generator is process-wide and may be seeded once only
            ou.RNG.setSeed(seed)
            _seeded.append(seed)
        self.dof = len(lower)
        self.is_valid = is_valid
        self.resolution = resolution
        self.straight_line_first = True  # off only to measure what the shortcut saves
        self.space = ob.RealVectorStateSpace(self.dof)
        bounds = ob.RealVectorBounds(self.dof)
        for i in range(self.dof):
            bounds.setLow(i, float(lower[i]))
            bounds.setHigh(i, float(upper[i]))
        self.space.setBounds(bounds)
        self.setup = og.SimpleSetup(self.space)
        dof = self.dof
        self.setup.setStateValidityChecker(lambda s: is_valid(np.array(s[0:dof])))
        info = self.setup.getSpaceInformation()
        # OMPL's resolution is a fraction of the space's extent; convert from radians.
        info.setStateValidityCheckingResolution(min(1.0, resolution / self.space.getMaximumExtent()))
        planner = og.RRTConnect(info)
        # OMPL's default range is 20% of the space's extent (about 6 rad for a 6-DOF arm with
        # +-2 pi joints): long extensions that mostly collide. 1 rad halved solve times here.
        planner.setRange(extension)
        self.setup.setPlanner(planner)

    def plan(self, start: np.ndarray, goal: np.ndarray, *, time_limit: float, simplify_time: float) -> list[np.ndarray]:
        """Waypoints of a collision-free path start→goal (both included).

        Raises:
            PlanningFailed: the start or goal is invalid, or no path was found in ``time_limit`` s of
                this thread's CPU time.
        """
        if not self.is_valid(start):
            raise PlanningFailed("the start state is in collision")
        if not self.is_valid(goal):
            raise PlanningFailed("the goal state is in collision")
        if self.straight_line_first and segment_is_valid(start, goal, self.is_valid, self.resolution):
            return [np.array(start, dtype=float), np.array(goal, dtype=float)]
        self.setup.clear()
        s = self.space.allocState()
        s[0 : self.dof] = [float(v) for v in start]
        g = self.space.allocState()
        g[0 : self.dof] = [float(v) for v in goal]
        self.setup.setStartAndGoalStates(s, g)
        if not self._solve(time_limit):
            raise PlanningFailed(f"no collision-free joint path was found in {time_limit:g} s of planning")
        path = self.setup.getSolutionPath()
        vertices = [np.array(path.getState(i)[0 : self.dof]) for i in range(path.getStateCount())]
        return self.shortcut(vertices, time.perf_counter() + simplify_time)

    def _solve(self, cpu_budget: float) -> bool:
        """Run RRTConnect until it finds a path or has had ``cpu_budget`` s of this thread's CPU.

        A wall-clock budget is a CPU budget only on an idle machine: beside other work, 0.4 s of
        wall clock gave the planner a fraction of that and a reachable goal failed. OMPL times its
        solve by the wall clock, so it runs in short slices, each continuing the trees of the last
        (RRTConnect keeps them until ``clear``), until the thread's own CPU time is spent.
        """
        spent_from = time.thread_time()
        while (remaining := cpu_budget - (time.thread_time() - spent_from)) > 0:
            if self.setup.solve(min(remaining, SOLVE_SLICE)) and self.setup.haveExactSolutionPath():
                return True
        return False

    def shortcut(self, vertices: list[np.ndarray], deadline: float) -> list[np.ndarray]:
        """Greedy shortcutting: from each kept vertex jump to the farthest one in straight sight.

        OMPL's simplifySolution overran its time budget by 10-30x here (its shortcut rounds
        call the Python validity checker thousands of times); RRTConnect's raw paths have few
        vertices, so this O(n^2) pass of early-exiting line checks is both bounded and enough.
        """
        out = [vertices[0]]
        i = 0
        while i < len(vertices) - 1:
            j = len(vertices) - 1
            while j > i + 1 and (
                time.perf_counter() > deadline
                or not segment_is_valid(vertices[i], vertices[j], self.is_valid, self.resolution)
            ):
                j -= 1
            out.append(vertices[j])
            i = j
        return out
