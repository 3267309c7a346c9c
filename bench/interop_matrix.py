"""The interop matrix: ``caretaker interop`` (every profile but ``at``) against Caretaker's bridge and the Rust
``rosbridge-server-rs``, both local, into one report folder; prints the matrix as Markdown and the
time each run took.

Usage: ``.venv/bin/python bench/interop_matrix.py [--report DIR]`` (default: a temporary folder).

Caretaker's bridge runs with a shared secret, so the ``auth`` profile is checked; the Rust server
has none, and the suite still authenticates every connection, to see what it makes of ``auth``.
The Rust server runs as ``bench/rosbridge_bench.py`` runs it (symlink, ``LD_PRELOAD``,
``--no-rosapi``, loopback).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from bench.rosbridge_bench import VENV, start_rust, stop, wait_for_line
from interop.catalog import DEFAULT_PROFILES

SERVERS = ("caretaker-bridge", "rosbridge-server-rs")


def run_suite(url: str, report: Path, name: str, secret: Path, env: dict[str, str]) -> float:
    """One ``caretaker interop`` run; its wall time in seconds."""
    started = time.monotonic()
    profiles = ",".join((*DEFAULT_PROFILES, "auth"))  # no AT server stands behind these bridges
    argv = [str(VENV / "bin" / "caretaker"), "interop", url, "--profile", profiles, "--secret-file", str(secret)]
    result = subprocess.run(
        [*argv, "--report", str(report), "--name", name], env=env, capture_output=True, text=True, timeout=600
    )
    took = time.monotonic() - started
    print(result.stdout.split("\n\n")[-1].strip(), file=sys.stderr)
    print(f"{name}: exit {result.returncode}, {took:.1f} s", file=sys.stderr)
    return took


def matrix(report: Path) -> str:
    """The Markdown table of the report: one row per case, one column per server."""
    index = json.loads((report / "index.json").read_text())
    servers = [s for s in SERVERS if s in index]
    cases = list(index[servers[0]])
    lines = [
        "| case | title | statements | " + " | ".join(servers) + " |",
        "|---|---|---|" + "---|" * len(servers),
    ]
    for case in cases:
        first = index[servers[0]][case]
        cells = [index[s].get(case, {}).get("outcome", "") for s in servers]
        lines.append(f"| {case} | {first['title']} | {', '.join(first['statements'])} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--report", type=Path, help="report folder (default: a temporary one)")
    args = parser.parse_args()
    workdir = Path(tempfile.mkdtemp(prefix="interop-matrix-"))
    report = args.report or workdir / "report"
    secret = workdir / "secret"
    secret.write_text("interop-matrix-secret\n")
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.setdefault("ROS_DOMAIN_ID", "57")
    timings = {}
    bridge = subprocess.Popen(
        [str(VENV / "bin" / "caretaker"), "bridge", "--port", "0", "--auth-secret-file", str(secret)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        url = wait_for_line(bridge, r"^READY bridge", 60).split()[-1]
        timings["caretaker-bridge"] = run_suite(url, report, "caretaker-bridge", secret, env)
    finally:
        stop(bridge)
    rust, port = start_rust(env, workdir)
    try:
        timings["rosbridge-server-rs"] = run_suite(f"ws://127.0.0.1:{port}", report, "rosbridge-server-rs", secret, env)
    finally:
        stop(rust)
    print(matrix(report))
    print()
    for name, took in timings.items():
        print(f"{name}: {took:.1f} s")
    print(f"report: {report / 'index.html'}")


if __name__ == "__main__":
    main()
