"""The EVA arm's camera locates each hull target of a displaced Gateway (targets moved up to
4 cm and 8 deg each), from 1 m straight out along where the drawings put the target: what the
inspection procedure's stand-off sees. The arm starts with its camera on hull_a (views.py);
the other targets are out of its view, and are refused with the reason.
"""

from __future__ import annotations

import pytest
from perception_client import PerceptionClient, errors, located
from views import View

pytestmark = pytest.mark.slow(seconds=30)

SCENE = "eva"
ARM = View("ee_camera", "target/hull_a", 1.0, 0.0, 90.0)  # the module's stack (conftest.py)


def test_the_eva_camera_locates_a_hull_target(client: PerceptionClient) -> None:
    answer = client.locate("target/hull_a", "ee_camera")
    assert answer.success, answer.message
    mm, deg = errors(located(answer), client.truth("target/hull_a"))
    print(f"ee_camera, hull_a: {mm:.2f} mm, {deg:.3f} deg, residual {answer.residual_px:.2f} px")
    assert mm <= 5.0 and deg <= 1.0, f"{answer.message}: {mm:.2f} mm and {deg:.3f} deg from the truth"
    assert answer.markers == "30,31" and answer.offset_mm > 5.0


def test_a_target_out_of_view_is_refused(client: PerceptionClient) -> None:
    answer = client.locate("target/hull_d", "ee_camera")
    assert not answer.success and "none of its markers (36, 37) is seen" in answer.message, answer.message
