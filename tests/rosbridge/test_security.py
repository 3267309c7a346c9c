"""Safe by default: allow-lists answered, size limit (1009), shared-secret/HMAC auth, TLS."""

from __future__ import annotations

import hashlib
import hmac
import ssl
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from websockets.exceptions import ConnectionClosed

from .rosbridge_support import RawClient, bridge_url
from support.processes import ManagedProcess, caretaker

SECRET = "s3cret-for-tests"


@pytest.fixture(scope="module")
def guarded(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, int]]:
    """A bridge with allow-lists, a 4 KiB frame limit and a shared secret."""
    secret_file = tmp_path_factory.mktemp("secret") / "secret"
    secret_file.write_text(SECRET + "\n")
    process = caretaker("bridge", "--port", "0", "--topics-glob", "/allowed/*", "--services-glob", "/peer/set_*",
                        "--actions-glob", "/allowed/*", "--max-message-size", "4096",
                        "--auth-secret-file", str(secret_file), env=ros_env)
    yield from _serve(process)


def _serve(process: ManagedProcess) -> Iterator[tuple[str, int]]:
    try:
        process.wait_ready(60)
        host, port = bridge_url(process).split("//")[1].rsplit(":", 1)
        yield host, int(port)
    finally:
        process.stop()


def authenticated(address: tuple[str, int]) -> RawClient:
    client = RawClient(*address)
    client.send({"op": "auth", "token": SECRET})
    client.send({"op": "set_level", "level": "error"})
    return client


def test_refused_names_are_answered(guarded: tuple[str, int]) -> None:
    client = authenticated(guarded)
    try:
        status = client.request({"op": "subscribe", "id": 1, "topic": "/secret/topic", "type": "std_msgs/String"},
                                "status")
        assert "topic /secret/topic is not allowed" in status["msg"] and status["id"] == 1
        answer = client.request({"op": "call_service", "id": 2, "service": "/peer/slow"}, "service_response")
        assert answer["result"] is False and "service /peer/slow is not allowed" in answer["values"]
        answer = client.request({"op": "send_action_goal", "id": 3, "action": "/peer/follow",
                                 "action_type": "caretaker_sim_msgs/action/FollowJointTrajectory"}, "action_result")
        assert answer["result"] is False and "action /peer/follow is not allowed" in answer["values"]
        allowed = client.request({"op": "call_service", "id": 4, "service": "/rosapi/get_ros_version"},
                                 "service_response")
        assert allowed["result"] is True
        client.send({"op": "subscribe", "id": 5, "topic": "/allowed/x", "type": "std_msgs/String"})
        still_up = client.request({"op": "call_service", "id": 6, "service": "/rosapi/get_ros_version"},
                                  "service_response")
        assert still_up["id"] == 6
    finally:
        client.close()


def test_oversized_frame_closes_with_1009(guarded: tuple[str, int]) -> None:
    client = authenticated(guarded)
    client.send({"op": "publish", "topic": "/allowed/big", "type": "std_msgs/String", "msg": {"data": "x" * 8000}})
    with pytest.raises(ConnectionClosed) as closed:
        client.receive(timeout=20)
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009


@pytest.mark.parametrize("first_message", [
    {"op": "call_service", "service": "/rosapi/get_ros_version"},
    {"op": "auth", "token": "wrong"},
    {"op": "auth", "mac": "00", "client": "c", "dest": "d", "rand": "r", "t": 0, "level": "user", "end": 0},
])
def test_unauthenticated_clients_are_closed_with_1008(guarded: tuple[str, int], first_message: dict) -> None:
    client = RawClient(*guarded)
    client.send(first_message)
    with pytest.raises(ConnectionClosed) as closed:
        client.receive(timeout=20)
    assert closed.value.rcvd.code == 1008


def test_hmac_authentication_is_accepted(guarded: tuple[str, int]) -> None:
    now = int(time.time())
    fields = {"client": "127.0.0.1", "dest": "127.0.0.1", "rand": "abc123", "t": now, "level": "user", "end": now + 60}
    text = "".join(str(fields[k]) for k in ("client", "dest", "rand", "t", "level", "end"))
    mac = hmac.new(SECRET.encode(), text.encode(), hashlib.sha256).hexdigest()
    client = RawClient(*guarded)
    try:
        client.send({"op": "auth", "mac": mac, **fields})
        answer = client.request({"op": "call_service", "service": "/rosapi/get_ros_version"}, "service_response")
        assert answer["result"] is True
    finally:
        client.close()


@pytest.fixture(scope="module")
def tls_bridge(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, int, Path]]:
    directory = tmp_path_factory.mktemp("tls")
    cert, key = directory / "cert.pem", directory / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
                    "-addext", "subjectAltName=IP:127.0.0.1", "-keyout", str(key), "-out", str(cert)],
                   check=True, capture_output=True)
    process = caretaker("bridge", "--port", "0", "--certfile", str(cert), "--keyfile", str(key), env=ros_env)
    for host, port in _serve(process):
        yield host, port, cert


def test_tls_serves_wss(tls_bridge: tuple[str, int, Path]) -> None:
    from websockets.sync.client import connect

    host, port, cert = tls_bridge
    context = ssl.create_default_context(cafile=str(cert))
    with connect(f"wss://{host}:{port}", ssl=context, open_timeout=20) as connection:
        connection.send('{"op":"call_service","service":"/rosapi/get_ros_version","id":"tls"}')
        assert '"result":true' in connection.recv(timeout=20)
