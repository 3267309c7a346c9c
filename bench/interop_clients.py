"""The clients matrix of docs/interop.md: ``caretaker interop --serve`` against each client, one report.

    .venv/bin/python bench/interop_clients.py [--report DIR]

Runs the scripted server (``python -m interop.scripted_server``) once per client with that
client's driver — roslibpy, roslibjs (Node, tests/js/node_modules), the project's Python client
and its Java client (java/pax-plugins/target/pax-plugins.jar) — into one report directory
(default /tmp/interop-clients: index.json, index.html), then prints the matrix as Markdown.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DRIVERS = REPO / "python" / "interop" / "clients"
JAR = REPO / "java" / "pax-plugins" / "target" / "pax-plugins.jar"


def drivers() -> dict[str, list[str]]:
    """Client name → its driver's command (the server's URL is appended)."""
    return {
        "roslibpy": [sys.executable, "-m", "interop.clients.roslibpy_driver"],
        "roslibjs": ["node", str(DRIVERS / "roslibjs_driver.js"), "--"],
        "python": [sys.executable, str(REPO / "tests" / "interop_clients" / "rosbridge_wire_driver.py")],
        "java": ["java", "-cp", f"{JAR}:/usr/share/java/gson.jar", str(DRIVERS / "JavaDriver.java")],
    }


def run_one(command: list[str], report: Path) -> None:
    server = subprocess.Popen(
        [sys.executable, "-m", "interop.scripted_server", "--port", "0", "--report", str(report), "--timeout", "90"],
        stdout=subprocess.PIPE,
        text=True,
        cwd=REPO,
    )
    try:
        assert server.stdout is not None
        url = re.search(r"ws://127\.0\.0\.1:\d+", server.stdout.readline())
        if url is None:
            raise SystemExit("the scripted server did not start")
        if command[-1] == "--":  # the roslibjs driver takes the URL, then its node_modules
            command = [*command[:-1], url.group(0), str(REPO / "tests" / "js" / "node_modules")]
        else:
            command = [*command, url.group(0)]
        subprocess.run(command, check=True, capture_output=True, timeout=120, cwd=REPO)
        server.communicate(timeout=90)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--report", type=Path, default=Path("/tmp/interop-clients"))
    args = parser.parse_args()
    for name, command in drivers().items():
        print(f"running {name} ...", file=sys.stderr)
        run_one(command, args.report)
    index = json.loads((args.report / "index.json").read_text())
    clients = list(index)
    cases = sorted({case for results in index.values() for case in results})
    print("| case | " + " | ".join(clients) + " |")
    print("|---|" + "---|" * len(clients))
    for case in cases:
        title = index[clients[0]][case]["title"]
        print(f"| {case} {title} | " + " | ".join(index[c][case]["outcome"] for c in clients) + " |")
    for client in clients:
        for case, record in index[client].items():
            if record["outcome"] != "OK":
                print(f"- {client} {case} {record['outcome']}: {record['observed']}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
