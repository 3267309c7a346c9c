"""``--serve`` checks real clients: roslibpy, roslibjs (Node), the project's Python and Java clients.

Each test starts the scripted server (``caretaker interop --serve``) as a process, runs one
client's driver against it as another process, and reads the report the server wrote. The report
must be complete (every case an outcome, the frames that show it), and the outcomes must be what
each client really does: for the project's clients they are read from their code (cited per
case), for roslibpy 2.1.0 and roslib 2.1.0 from theirs.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.slow(seconds=35)

REPO = Path(__file__).resolve().parents[2]
DRIVERS = REPO / "python" / "interop" / "clients"
CASES = [f"clients.{n}" for n in range(1, 7)]
OUTCOMES = {"OK", "NON-STRICT", "INFORMATIONAL", "UNIMPLEMENTED", "FAILED"}


def serve_against(driver: Callable[[str], list[str]], report: Path) -> tuple[dict[str, Any], int, str]:
    """Run the scripted server and one driver; the server's report of that client, its exit code, its output."""
    server = subprocess.Popen(
        [str(REPO / ".venv" / "bin" / "caretaker"), "interop", "--serve", "0", "--report", str(report)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=REPO,
    )
    try:
        assert server.stdout is not None
        first = server.stdout.readline()
        found = re.search(r"ws://127\.0\.0\.1:\d+", first)
        assert found, f"the server did not say where it serves: {first!r}"
        run = subprocess.run(driver(found.group(0)), capture_output=True, text=True, timeout=90, cwd=REPO)
        assert run.returncode == 0, f"the driver failed:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
        output, _ = server.communicate(timeout=60)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    assert (report / "index.html").is_file()
    index = json.loads((report / "index.json").read_text())
    assert len(index) == 1, f"one client per run, got {list(index)}"
    return next(iter(index.values())), server.returncode, first + output


def outcomes(cases: dict[str, Any], output: str) -> dict[str, str]:
    """Every case's outcome, after checking that the report is complete."""
    assert sorted(cases) == CASES, f"cases in the report: {sorted(cases)}"
    for case, record in cases.items():
        assert record["outcome"] in OUTCOMES, f"{case}: {record['outcome']}"
        assert record["frames"], f"{case} has no frames: {record}"
        assert record["statements"] and record["expected"] and record["observed"], f"{case}: {record}"
        assert case in output, f"{case} has no line in the server's output:\n{output}"
    return {case: record["outcome"] for case, record in cases.items()}


def received(record: dict[str, Any]) -> list[dict[str, Any]]:
    """The messages a case received from the client (its reports included)."""
    return [json.loads(f["text"]) for f in record["frames"] if f["direction"] == "received"]


def test_project_python_client(tmp_path: Path) -> None:
    cases, code, output = serve_against(
        lambda url: [sys.executable, str(REPO / "tests" / "interop_clients" / "rosbridge_wire_driver.py"), url],
        tmp_path,
    )
    assert outcomes(cases, output) == {
        "clients.1": "OK",  # answers go to the future of their id (RosbridgeClient._calls)
        "clients.2": "UNIMPLEMENTED",  # _receive has no branch for the fragment op: dropped, the loop goes on
        "clients.3": "OK",  # a status is logged (warning for error/warning levels)
        "clients.4": "OK",  # _run reconnects after RECONNECT_S[0] and sends subscriptions and services again
        "clients.5": "OK",  # call() waits with asyncio.wait_for: LinkError "no answer in time"
        "clients.6": "NON-STRICT",  # a refused login is a warning in the log; the program sees "reconnecting"
    }, output
    assert code == 1  # an UNIMPLEMENTED case does not pass
    # the reconnection is the client's own: a second connection, with the same subscription id again
    drop = cases["clients.4"]
    subscribes = [message for message in received(drop) if message.get("op") == "subscribe"]
    assert len(subscribes) == 2 and subscribes[0]["id"] == subscribes[1]["id"], subscribes
    assert received(cases["clients.6"])[0]["op"] == "auth"  # the login is the first message
    # after a refusal _run only sleeps RECONNECT_S[0] and logs in again with the same secret
    assert "sent the refused login again" in cases["clients.6"]["observed"]


def test_project_java_client(tmp_path: Path) -> None:
    jar = REPO / "java" / "pax-plugins" / "target" / "pax-plugins.jar"
    assert jar.is_file(), f"{jar} is missing: run make setup (it builds the jar)"
    classpath = f"{jar}:/usr/share/java/gson.jar"
    cases, code, output = serve_against(
        lambda url: ["java", "-cp", classpath, str(DRIVERS / "JavaDriver.java"), url], tmp_path
    )
    # java/pax-plugins/README.md "The client, compared with jrosbridge", and Ros/Connection.java
    assert outcomes(cases, output) == {
        "clients.1": "OK",  # pending calls in a map by id
        "clients.2": "OK",  # FragmentBuffer reassembles by num
        "clients.3": "OK",  # status is logged at INFO
        "clients.4": "OK",  # reconnects from reconnectMin (0.1 s) and re-sends every feed and advertisement
        "clients.5": "OK",  # callServiceAndWait(request, timeout) throws RosTimeoutException
        "clients.6": "OK",  # close 1008 naming authentication: RosAuthException, no more reconnects
    }, output
    assert code == 0


def test_roslibpy(tmp_path: Path) -> None:
    cases, code, output = serve_against(
        lambda url: [sys.executable, "-m", "interop.clients.roslibpy_driver", url], tmp_path
    )
    # roslibpy 2.1.0: comm.py has handlers for neither fragment nor status (an exception is logged,
    # the message skipped); Twisted's ReconnectingClientFactory reconnects and topics and services
    # send themselves again; Service.call(timeout=) raises; authenticate() is sent once, unanswered
    assert outcomes(cases, output) == {
        "clients.1": "OK",
        "clients.2": "UNIMPLEMENTED",
        "clients.3": "OK",
        "clients.4": "OK",
        "clients.5": "OK",
        "clients.6": "NON-STRICT",
    }, output
    assert code == 1


def test_roslibjs(tmp_path: Path) -> None:
    modules = REPO / "tests" / "js" / "node_modules"
    assert (modules / "roslib").is_dir(), "roslib is not installed: run tools/setup.sh (npm ci in tests/js)"
    cases, code, output = serve_against(
        lambda url: ["node", str(DRIVERS / "roslibjs_driver.js"), url, str(modules)], tmp_path
    )
    # roslib 2.1.0: the transport reassembles fragments and emits status; Ros never reconnects by
    # itself; callService's timeout is only sent to the server
    assert outcomes(cases, output) == {
        "clients.1": "OK",
        "clients.2": "OK",
        "clients.3": "OK",
        "clients.4": "UNIMPLEMENTED",
        "clients.5": "UNIMPLEMENTED",
        "clients.6": "OK",
    }, output
    assert code == 1
    slow_call = next(m for m in received(cases["clients.5"]) if m.get("service") == "/interop/slow")
    assert slow_call["timeout"] == 0.5  # roslibjs's timeout travels to the server only
