"""Time parameterization stays within velocity and acceleration limits and ends at rest."""

from __future__ import annotations

import numpy as np

from at_ros.time_parameterization import TimedPath, time_parameterize

VMAX = np.array([2.0, 2.0, 3.0])


def _check_limits(timed: TimedPath, vmax: np.ndarray, amax: float) -> None:
    assert np.all(np.diff(timed.times) > 0)
    dt = np.diff(timed.times)[:, None]
    finite_velocity = np.diff(timed.positions, axis=0) / dt
    assert np.all(np.abs(finite_velocity) <= vmax * 1.001)
    assert np.all(np.abs(timed.velocities) <= vmax * 1.001)
    accel = np.diff(timed.velocities, axis=0) / dt
    assert np.all(np.abs(accel) <= amax * 1.05)


def test_corner_path_within_limits_and_through_every_vertex() -> None:
    path = [np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([1.0, 1.5, -0.5])]
    timed = time_parameterize(path, VMAX, 2.0, velocity_scaling=0.5)
    _check_limits(timed, VMAX * 0.5, 2.0)
    np.testing.assert_allclose(timed.positions[0], path[0])
    np.testing.assert_allclose(timed.positions[-1], path[-1])
    assert any(np.allclose(p, path[1]) for p in timed.positions)  # the corner is reached, not cut
    assert np.allclose(timed.velocities[-1], 0)


def test_long_move_cruises_at_the_scaled_limit() -> None:
    timed = time_parameterize([np.zeros(3), np.array([4.0, 0, 0])], VMAX, 4.0, velocity_scaling=0.5)
    _check_limits(timed, VMAX * 0.5, 4.0)
    assert np.max(np.abs(timed.velocities[:, 0])) == np.float64(1.0)
    # 4 rad at 1 rad/s with 0.25 s ramps: 4.25 s.
    assert abs(timed.duration - 4.25) < 1e-6


def test_gentle_bends_are_not_stopped_at() -> None:
    s = np.linspace(0, 1, 30)
    path = np.stack([s, 0.1 * np.sin(s * np.pi), np.zeros_like(s)], axis=1)
    timed = time_parameterize(path, VMAX, 2.0)
    _check_limits(timed, VMAX, 2.0)
    speeds = np.linalg.norm(timed.velocities, axis=1)
    assert np.count_nonzero(speeds[1:-1] < 1e-9) == 0  # no stop in between


def test_no_motion_gives_a_single_point() -> None:
    timed = time_parameterize([np.ones(3), np.ones(3)], VMAX, 2.0)
    assert len(timed.times) == 1 and timed.duration == 0.0
