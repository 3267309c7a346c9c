"""Each test session claims a ROS domain no other session on the machine holds."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from support.ros_domain import DOMAINS, claim_ros_domain

TESTS = Path(__file__).resolve().parents[1]


def test_a_claimed_domain_is_not_given_to_another_session_until_its_holder_ends() -> None:
    mine = claim_ros_domain(start=0)
    other = (
        f"import sys; sys.path.insert(0, {str(TESTS)!r}); from support.ros_domain import claim_ros_domain; "
        "print(claim_ros_domain(start=0))"
    )
    first = subprocess.run([sys.executable, "-c", other], capture_output=True, text=True, timeout=30, check=True)
    second = subprocess.run([sys.executable, "-c", other], capture_output=True, text=True, timeout=30, check=True)
    assert int(first.stdout) != mine and int(first.stdout) in DOMAINS
    assert int(second.stdout) == int(first.stdout)  # the first one's lock ended with its process
