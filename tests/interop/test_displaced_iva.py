"""The IVA filter change in a habitat that is not where its drawings put it.

``caretaker demo --displace SEED`` (support/demos.py, as in test_demos.py): the CDRA cabinet and
the rack, with the filters seated in them, moved by up to 4 cm and 8 degrees, told to nobody but
the simulator. The procedure locates each object from its markers in the robot's camera and
registers the template there, with no manual registration, and the demo checks the world where
the objects really are. What perception found is compared with where the seed put each object,
and every registration is either where the drawings put the object (to look at it from there)
or exactly a located pose.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from support.demos import displaced_demo

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=120), pytest.mark.timeout(900)]


@pytest.mark.parametrize("seed", [3, 17, 42])
def test_iva_filter_change_in_a_displaced_habitat_locates_every_object_it_registers(
    seed: int, tmp_path: Path, ros_env: dict[str, str]
) -> None:
    checks, located = displaced_demo("iva", seed, tmp_path, ros_env, max_deg=1.0)
    # measured where the objects are (sim/check/frames), not where the drawings put them
    assert len(checks) == 3 and checks[0].startswith("verified: filter/CDRA-F-0007 is at rack/slot_3: "), checks
    assert list(located) == [
        "cabinet/slot",
        "filter/CDRA-F-0007",
        "rack/slot_3",
        "rack/slot_1",
        "filter/CDRA-F-0012",
    ]
