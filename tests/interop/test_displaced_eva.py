"""The EVA inspection in a habitat that is not where its drawings put it.

``caretaker demo --displace SEED`` (support/demos.py, as in test_demos.py): each hull target
moved by up to 4 cm and 8 degrees, told to nobody but the simulator. The procedure locates each
object from its markers in the robot's camera and registers the template there, with no manual
registration, and the demo checks the world where the objects really are. What perception found
is compared with where the seed put each object, and every registration is either where the
drawings put the object (to look at it from there) or exactly a located pose.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from support.demos import displaced_demo

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=120), pytest.mark.timeout(900)]


@pytest.mark.parametrize("seed", [3, 17, 42])
def test_eva_inspection_of_a_displaced_hull_registers_each_target_where_the_camera_finds_it(
    seed: int, tmp_path: Path, ros_env: dict[str, str]
) -> None:
    # from where the drawings put the target, so up to 8 degrees off its axis: the accuracy bar of
    # a square view (5 mm, 1 degree at 1 m) is tests/perception's; this is the demo's
    checks, located = displaced_demo("eva", seed, tmp_path, ros_env, max_deg=2.0)
    assert checks == ["verified: images of hull_a, hull_b, hull_c, hull_d captured (4 non-empty files)"]
    assert sorted(located) == [f"target/hull_{c}" for c in "abcd"]
