"""The frame table: latest named poses, world as identity, unknown names answered with the known ones."""

from __future__ import annotations

import numpy as np
import pytest

from at_ros.frames import FrameTable, UnknownFrame
from at_ros.transforms import from_xyz_rpy


def test_lookup_returns_copies_of_the_latest_poses() -> None:
    table = FrameTable()
    slot = from_xyz_rpy([0.86, 0.25, 1.05], [0, 0, 0])
    table.update(["rack/slot_3"], [slot])
    found = table.lookup("rack/slot_3")
    np.testing.assert_allclose(found, slot)
    found[0, 3] = 99.0  # callers cannot corrupt the table
    np.testing.assert_allclose(table.lookup("rack/slot_3"), slot)
    table.update(["tool0"], [np.eye(4)])  # each message replaces the whole set
    with pytest.raises(UnknownFrame, match="known frames: world, tool0"):
        table.lookup("rack/slot_3")


def test_world_and_empty_name_are_the_identity_even_before_any_frame() -> None:
    table = FrameTable()
    np.testing.assert_allclose(table.lookup("world"), np.eye(4))
    np.testing.assert_allclose(table.lookup(""), np.eye(4))
    assert table.age == float("inf")
    with pytest.raises(UnknownFrame, match="no frames received on /sim/frames yet"):
        table.lookup("robot_base")


def test_lookup_waits_for_a_frame_published_meanwhile() -> None:
    import threading

    table = FrameTable()
    publisher = threading.Timer(0.2, lambda: table.update(["robot_base"], [np.eye(4)]))
    publisher.start()
    np.testing.assert_allclose(table.lookup("robot_base", timeout=30.0), np.eye(4))
    publisher.join()
