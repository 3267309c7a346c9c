"""roslibjs (npm ``roslib``) under Node against the real bridge: tests/js/roslib_check.mjs."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

JS = Path(__file__).resolve().parents[1] / "js"


def test_roslibjs_client_works_unchanged(bridge: tuple[str, int]) -> None:
    assert (JS / "node_modules" / "roslib").is_dir(), "roslib is not installed: run tools/setup.sh (npm ci in tests/js)"
    host, port = bridge
    run = subprocess.run(
        ["node", str(JS / "roslib_check.mjs"), f"ws://{host}:{port}"], capture_output=True, text=True, timeout=240
    )
    checks = {entry["check"]: entry for entry in map(json.loads, run.stdout.splitlines())}
    failed = {name: entry.get("error") for name, entry in checks.items() if not entry["ok"]}
    assert not failed, f"roslibjs checks failed: {failed}\n{run.stderr[-2000:]}"
    assert set(checks) == {
        "connect",
        "getTopics",
        "pubsub",
        "callService",
        "failedServiceCall",
        "subscribe png",
        "subscribe cbor",
        "advertiseService",
        "sendGoal",
    }
    assert run.returncode == 0
    assert checks["sendGoal"]["detail"]["feedback"] == 2
