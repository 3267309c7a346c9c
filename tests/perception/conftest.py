"""The displaced IVA world with test cameras (``views.py``), and the perception node on it.

One robot side per test module, started from a deployment as the product starts one: the
simulator (displaced, with the test cameras), perception, the command ledger and the rosbridge
server (so PAX can command it through the binding). The tests that change the world (covering a
marker) put it back.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from perception_client import PerceptionClient
from views import DISPLACE_SEED, views, write_scene

from caretaker.stack import Stack
from support.stack import robot_parts, write_deployment

PARTS = ("sim", "perception", "ledger", "bridge")


@pytest.fixture(scope="module")
def stack(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory, ros_env: dict[str, str]
) -> Iterator[Stack]:
    """The robot side of the module's ``SCENE`` (default iva) on the displaced world (no planner,
    no AT server), with the IVA test cameras of ``views()``, or with the module's ``ARM`` view
    (the arm starting with its camera there) and no test cameras."""
    folder = tmp_path_factory.mktemp("perception")
    arm, name = getattr(request.module, "ARM", None), getattr(request.module, "SCENE", "iva")
    scene = write_scene(folder, [] if arm else views(), arm, name)
    deployment = write_deployment(folder, name, scene=str(scene), displace=DISPLACE_SEED)
    with robot_parts(deployment, ros_env, parts=PARTS) as parts:
        yield parts


@pytest.fixture(scope="module")
def client(stack: Stack) -> Iterator[PerceptionClient]:
    c = PerceptionClient()
    try:
        yield c
    finally:
        c.close()
