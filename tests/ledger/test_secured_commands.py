"""The PAX chain over a secured link, end to end: PaxHost (JPype) → Java plugins and ledger client
→ wss:// with HMAC auth → `caretaker bridge --certfile --keyfile --auth-secret-file` → `caretaker
ledger` → a counting service. Executions are counted on the habitat side, by the service itself."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from caretaker.certs import make_link_credentials
from support.processes import ManagedProcess, caretaker

from .ledger_support import LedgerClient

pytestmark = pytest.mark.ros

SYSREP = Path(__file__).with_name("ledger_test_sysrep.yaml")


class Habitat:
    """The habitat's bridge (restartable on its port) and ledger, with the files they use."""

    def __init__(self, env: dict[str, str], directory: Path) -> None:
        self.env = env
        self.directory = directory
        files = make_link_credentials(directory, ["127.0.0.1"], days=2)  # as `caretaker certs` makes them
        self.ca, self.cert, self.key = files["ca.pem"], files["bridge.pem"], files["bridge.key"]
        self.secret = files["rosbridge.secret"]
        self.processes: list[ManagedProcess] = []
        self.ledger = self._start("ledger", "--state-dir", str(directory / "state"))
        self.bridge = self.start_bridge("0")
        self.url = self.bridge.wait_ready().split()[-1]
        self.port = self.url.rsplit(":", 1)[1]

    def _start(self, *args: str) -> ManagedProcess:
        process = caretaker(*args, env=self.env)
        self.processes.append(process)
        process.wait_ready(60)
        return process

    def start_bridge(self, port: str) -> ManagedProcess:
        return self._start(
            "bridge",
            "--port",
            port,
            "--certfile",
            str(self.cert),
            "--keyfile",
            str(self.key),
            "--auth-secret-file",
            str(self.secret),
        )

    def binding(self, *, secret: bool = True) -> Path:
        security = f"  ca_file: {self.ca.name}\n" + (f"  secret_file: {self.secret.name}\n" if secret else "")
        path = self.directory / ("binding.yaml" if secret else "binding-without-secret.yaml")
        path.write_text(
            f"robot: habitat\nrosbridge: {self.url}\nlink:\n  outage_budget: 60\nsecurity:\n{security}"
            f"systems:\n- sysrep: {SYSREP}\n  plugins: [ros_convention]\n  namespace: /ledger_test\n"
            "  options: {call_timeout: 60}\n"
        )
        return path

    def stop(self) -> None:
        for process in reversed(self.processes):
            process.stop()


@pytest.fixture(scope="module")
def habitat(
    ros_env: dict[str, str], peer: ManagedProcess, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Habitat]:
    place = Habitat(ros_env, tmp_path_factory.mktemp("habitat"))
    try:
        yield place
    finally:
        place.stop()


@pytest.fixture(scope="module")
def host(habitat: Habitat) -> Iterator[object]:
    from pride.pax_host import PaxHost

    with PaxHost(habitat.binding()) as pax:
        yield pax


def test_commands_cross_the_authenticated_wss_link_once_per_key(host: object, client: LedgerClient) -> None:
    before = client.counts().get("count", 0)
    done = host.execute("ledger_test", "count", {}, key="run-s/1.1/1")  # type: ignore[attr-defined]
    assert (done.success, done.outcome, done.message) == (True, "succeeded", f"count {before + 1}")
    again = host.execute("ledger_test", "count", {}, key="run-s/1.1/1")  # type: ignore[attr-defined]
    assert again.success and again.message == done.message  # the recorded outcome, not a second run
    refused = host.execute("ledger_test", "refuse", {}, key="run-s/1.2/1")  # type: ignore[attr-defined]
    assert (refused.success, refused.outcome, refused.message) == (False, "failed", "refused by the peer")
    assert client.counts()["count"] == before + 1


def test_a_client_without_the_secret_is_refused(habitat: Habitat) -> None:
    from pride.pax_host import PaxError, PaxHost

    with pytest.raises(PaxError, match=r"refused authentication \(close 1008: authentication required"):
        PaxHost(habitat.binding(secret=False))


def test_a_command_whose_connection_dies_mid_call_is_resent_and_runs_once(
    habitat: Habitat, host: object, client: LedgerClient, peer: ManagedProcess
) -> None:
    before = client.counts().get("hold", 0)
    results: list[object] = []
    call = threading.Thread(
        target=lambda: results.append(
            host.execute(  # type: ignore[attr-defined]
                "ledger_test", "hold", {}, key="run-s/2.1/1"
            )
        )
    )
    call.start()
    peer.wait_for_line(rf"^CALLED hold {before + 1}$", 60)
    habitat.bridge.kill()  # the connection drops with the command in flight
    habitat.bridge = habitat.start_bridge(habitat.port)
    habitat.ledger.wait_for_line(r"run-s/2\.1/1: re-sent while in progress: joining the call", 60)
    client.release()
    call.join(90)
    assert not call.is_alive()
    result = results[0]
    assert (result.success, result.outcome) == (True, "succeeded"), result  # type: ignore[attr-defined]
    assert result.message == f"held {before + 1}"  # type: ignore[attr-defined]
    assert client.counts()["hold"] == before + 1
