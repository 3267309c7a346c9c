"""The one way tests start a robot side: from a deployment file, as the product does.

Two forms, both stopping everything they started:

- :func:`stack_up`: ``caretaker up DEPLOYMENT`` as one supervised process (restarts, the world
  ending the stack), on a free port; yields an :class:`UpStack` with the process and its URL.
- :func:`robot_parts`: the deployment's parts started one by one in the test process by the
  launcher's own :class:`caretaker.stack.Stack`, so a test can kill one part and start it again
  when it chooses (the bridge comes back on the same port, the AT server with its instances).

:func:`write_deployment` makes a variant of a shipped deployment in a test folder (another
template library, another binding), its paths still leading to the checkout's files.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from caretaker.deployment import load_deployment, resolve_deployment
from caretaker.processes import ManagedProcess, caretaker
from caretaker.stack import Stack

__all__ = ["UpStack", "robot_parts", "stack_up", "write_deployment"]

#: Keys of a deployment whose values are paths (a list of paths for bindings).
_PATH_KEYS = ("scene", "robot", "templates", "robots", "capture_dir", "state_dir")


@dataclass
class UpStack:
    process: ManagedProcess
    url: str  # the rosbridge server's ws:// URL


@contextmanager
def stack_up(
    deployment: str | Path,
    env: dict[str, str],
    *,
    time_scale: str = "0",
    timeout: float = 180.0,
    displace: int | None = None,
) -> Iterator[UpStack]:
    """``caretaker up DEPLOYMENT --bridge-port 0`` (``--displace SEED`` with ``displace``), up until
    the ``READY stack`` line, stopped after."""
    extra = ["--displace", str(displace)] if displace is not None else []
    up = caretaker("up", str(deployment), "--time-scale", time_scale, "--bridge-port", "0", *extra, env=env, name="up")
    try:
        line = up.wait_for_line(r"^READY stack ", timeout)
        yield UpStack(up, line.split()[-1])
    finally:
        up.stop()


@contextmanager
def robot_parts(
    deployment: str | Path,
    env: dict[str, str],
    *,
    parts: Sequence[str] | None = None,
    time_scale: float = 0.0,
    ready_timeout: float = 180.0,
) -> Iterator[Stack]:
    """The deployment's ``parts`` (default: all) started in order; the rosbridge server on a free
    port (``stack.bridge_url``). Kill one with ``stack.processes[name].kill()``, start it again
    with ``stack.start_part(name)``."""
    stack = Stack(
        load_deployment(deployment),
        time_scale=time_scale,
        bridge_port=0,
        parts=parts,
        env=env,
        ready_timeout=ready_timeout,
    )
    try:
        stack.start()
        yield stack
    finally:
        stack.stop()


def write_deployment(folder: Path, base: str = "iva", **changes: Any) -> Path:
    """A copy of shipped deployment ``base`` in ``folder`` with ``changes`` applied (``None``
    removes a key); paths written in the shipped file are made absolute so they still resolve."""
    source = resolve_deployment(base)
    data = yaml.safe_load(source.read_text())
    for key in _PATH_KEYS:
        if key in data:
            data[key] = str((source.parent / data[key]).resolve())
    data["bindings"] = [str((source.parent / b).resolve()) for b in data.get("bindings", [])]
    if "demo" in data:
        for key in ("procedure", "binding"):
            data["demo"][key] = str((source.parent / data["demo"][key]).resolve())
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    path = folder / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
