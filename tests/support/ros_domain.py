"""A ROS domain id that no other test session on this machine is using.

Test sessions (a CI run, a developer's run, a benchmark beside them) must not see each other's
nodes. Each claims a domain by holding an exclusive lock on a per-domain file for as long as
the session's process lives; the kernel releases it when the process ends, however it ends.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path
from typing import IO

__all__ = ["claim_ros_domain"]

#: Domain ids whose DDS ports do not overlap Linux's ephemeral port range (ROS 2 docs: 0-101).
DOMAINS = range(1, 102)

_held: list[IO[bytes]] = []  # the open lock files: closing one would release its domain


def claim_ros_domain(start: int = os.getpid()) -> int:
    """Lock and return the first free domain id, searching from ``start`` (spreads sessions out).

    Raises:
        RuntimeError: every domain in :data:`DOMAINS` is held by another session.
    """
    folder = Path(tempfile.gettempdir())
    for offset in range(len(DOMAINS)):
        domain = DOMAINS[(start + offset) % len(DOMAINS)]
        handle = open(folder / f"caretaker-ros-domain-{domain}.lock", "wb")  # noqa: SIM115 - held for the session
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            continue
        _held.append(handle)
        return domain
    raise RuntimeError(f"every ROS domain in {DOMAINS.start}..{DOMAINS.stop - 1} is held by another test session")
