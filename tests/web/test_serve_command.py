"""``caretaker serve`` and ``caretaker accounts``: passwords, sessions, CSRF, slowed guessing, TLS.

The server is a real process (conftest.py); requests go over real sockets with urllib, the way a
script or an attacker's tool would, not through a browser.
"""

from __future__ import annotations

import http.client
import http.cookiejar
import json
import os
import ssl
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest
import websockets
from websockets.sync.client import connect

from caretaker.demo import DEMO_APPROVER, DEMO_USER, demo_approver, demo_operator
from console.accounts import AccountStore, Role
from console.catalog import CameraSettings
from console.server import main
from support.certificates import self_signed_certificate
from support.processes import caretaker
from support.web_server import PEOPLE, REPO, WebServer

Reply = tuple[int, dict[str, Any], dict[str, str]]


class Client:
    """A cookie-keeping HTTP client of one server, as a script would use it."""

    def __init__(self, url: str, *, context: ssl.SSLContext | None = None) -> None:
        self.url = url
        self.jar = http.cookiejar.CookieJar()
        handlers: list[Any] = [urllib.request.HTTPCookieProcessor(self.jar)]
        if context is not None:
            handlers.append(urllib.request.HTTPSHandler(context=context))
        self.opener = urllib.request.build_opener(*handlers)
        self.csrf: str | None = None

    def call(self, method: str, path: str, body: dict | None = None, headers: dict[str, str] | None = None) -> Reply:
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(
            self.url + path, data=data, method=method, headers={"Content-Type": "application/json", **(headers or {})}
        )
        try:
            with self.opener.open(request, timeout=30) as response:
                return response.status, json.loads(response.read()), dict(response.headers)
        except urllib.error.HTTPError as error:
            text = error.read()
            return (
                error.code,
                json.loads(text) if text.startswith(b"{") else {"error": text.decode()},
                dict(error.headers),
            )

    def sign_in(self, user: str, password: str | None = None) -> Reply:
        reply = self.call(
            "POST", "/api/session", {"user": user, "password": PEOPLE[user][2] if password is None else password}
        )
        if reply[0] == 200:
            self.csrf = reply[1]["csrf"]
        return reply

    def act(self, path: str, body: dict) -> Reply:
        return self.call("POST", path, body, {"X-CSRF-Token": self.csrf or ""})


def accounts(db: str, *args: str, password: str | None = None) -> subprocess.CompletedProcess[str]:
    """``caretaker accounts --db DB ARGS``, the password (if any) on stdin as a script gives it."""
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "accounts", "--db", db, *args],
        input=password,
        capture_output=True,
        text=True,
        timeout=120,  # about 1 s of CPU, but beside the whole suite on two cores it waits for it
    )


#: Thirteen CLI runs one after another, each about 1 s of CPU: on two cores shared with the rest
#: of the suite (10-40 processes runnable) they took 211 s in a quiet fresh clone and over 300 s
#: in a loaded one. What it checks is not a time.
@pytest.mark.timeout(900)
def test_accounts_are_managed_with_passwords_from_stdin_never_arguments(tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'ground.db'}"
    added = accounts(db, "add", "dave", "--role", "operator", "--name", "Dave", password="dave-secret-1\n")
    assert added.returncode == 0, added.stderr
    assert accounts(db, "add", "erin", "--role", "observer", password="erin-secret-1\n").returncode == 0
    listed = accounts(db, "list")
    assert listed.stdout.splitlines() == ["dave\toperator\tDave", "erin\tobserver\t"]

    refused = {
        "a password on the command line": accounts(db, "add", "frank", "--role", "operator", "--password", "x"),
        "a short password": accounts(db, "add", "frank", "--role", "operator", password="short\n"),
        "no password": accounts(db, "add", "frank", "--role", "operator", password=""),
        "a taken user id": accounts(db, "add", "dave", "--role", "observer", password="another-secret\n"),
        "an unknown user": accounts(db, "set-password", "mallory", password="whatever-long\n"),
        "a bad user id": accounts(db, "add", "a b", "--role", "operator", password="whatever-long\n"),
    }
    for what, result in refused.items():
        assert result.returncode == 2, what
    assert "at least 8 characters" in refused["a short password"].stderr
    assert "no password on stdin" in refused["no password"].stderr
    assert "already has an account" in refused["a taken user id"].stderr
    assert "no account 'mallory'" in refused["an unknown user"].stderr

    store = AccountStore(db)
    try:
        assert store.verify("dave", "dave-secret-1") is not None and store.verify("dave", "dave-secret-2") is None
        assert accounts(db, "set-password", "dave", password="dave-secret-2\n").returncode == 0
        assert store.verify("dave", "dave-secret-1") is None and store.verify("dave", "dave-secret-2") is not None
        assert accounts(db, "set-role", "erin", "operator").returncode == 0
        assert store.get("erin").role is Role.OPERATOR
        assert accounts(db, "remove", "erin").returncode == 0
        assert store.get("erin") is None
    finally:
        store.close()
    assert "dave-secret" not in (tmp_path / "ground.db").read_bytes().decode("latin-1")  # only hashes are stored


def test_serve_binds_loopback_and_serves_nothing_before_sign_in(server: WebServer) -> None:
    assert server.url.startswith("http://127.0.0.1:")
    client = Client(server.url)
    assert client.call("GET", "/api/runs")[:2] == (401, {"error": "sign in first"})
    status, body, _ = client.call("POST", "/api/runs/any-run/actions", {"action": "perform", "instruction": "1.1"})
    assert (status, body["error"]) == (401, "sign in first")
    for user, password in (("alice", "not-alices-password"), ("mallory", "any-password-at-all")):
        status, body, _ = client.call("POST", "/api/session", {"user": user, "password": password})
        assert (status, body["error"]) == (401, "wrong user id or password")  # never says which was wrong
    assert client.call("POST", "/api/session", {"user": "alice"})[0] == 400

    ws_url = server.url.replace("http://", "ws://") + "/ws/runs/anything"
    with pytest.raises(websockets.InvalidStatus) as refused:  # closed before the handshake completes
        connect(ws_url, open_timeout=30)
    assert refused.value.response.status_code == 403


def test_state_changing_requests_need_the_sessions_csrf_token_and_this_sites_origin(server: WebServer) -> None:
    client = Client(server.url)
    status, body, headers = client.sign_in("bob")
    assert status == 200 and body["user"] == "bob" and len(body["csrf"]) >= 32
    cookie = headers["set-cookie"].lower()
    assert "httponly" in cookie and "samesite=strict" in cookie
    assert client.call("GET", "/api/session")[1]["csrf"] == body["csrf"]  # the page reads it after a reload

    action = {"action": "pause"}
    status, body, _ = client.call("POST", "/api/runs/no-such-run/actions", action)
    assert status == 403 and "X-CSRF-Token" in body["error"]
    status, body, _ = client.call("POST", "/api/runs/no-such-run/actions", action, {"X-CSRF-Token": "guessed"})
    assert status == 403 and "X-CSRF-Token" in body["error"]
    status, body, _ = client.call(
        "POST", "/api/runs/no-such-run/actions", action, {"X-CSRF-Token": client.csrf, "Origin": "http://evil.example"}
    )
    assert status == 403 and "another site" in body["error"]
    status, body, _ = client.call(  # an Origin no browser sends is refused the same way, not a server error
        "POST", "/api/runs/no-such-run/actions", action, {"X-CSRF-Token": client.csrf, "Origin": "http://[evil"}
    )
    assert status == 403 and "another site" in body["error"]
    status, body, _ = client.act("/api/runs/no-such-run/actions", action)
    assert status == 404 and "not live on any console" in body["error"]  # past the checks: no such run

    other = Client(server.url)  # a second session has a token of its own; bob's does not work there
    other.sign_in("alice")
    status, _, _ = other.call("POST", "/api/runs/no-such-run/actions", action, {"X-CSRF-Token": client.csrf})
    assert status == 403

    assert client.call("DELETE", "/api/session", None, {"X-CSRF-Token": client.csrf})[0] == 200
    assert client.call("GET", "/api/runs")[0] == 401


def _from_address(url: str, address: str, body: dict) -> tuple[int, dict[str, str]]:
    """POST a sign-in from a given loopback source address (another console on the network)."""
    host, port = url.removeprefix("http://").split(":")
    connection = http.client.HTTPConnection(host, int(port), timeout=30, source_address=(address, 0))
    try:
        connection.request("POST", "/api/session", json.dumps(body), {"Content-Type": "application/json"})
        response = connection.getresponse()
        response.read()
        return response.status, dict(response.getheaders())
    finally:
        connection.close()


def test_repeated_failures_slow_that_user_from_that_address_not_the_real_user_elsewhere(server: WebServer) -> None:
    guess = {"user": "bob", "password": "guess-number-n"}
    for _ in range(5):
        assert _from_address(server.url, "127.0.0.3", guess)[0] == 401
    status, headers = _from_address(server.url, "127.0.0.3", {"user": "bob", "password": PEOPLE["bob"][2]})
    assert status == 429 and int(headers["retry-after"]) >= 1  # even the right password waits from there
    status, _ = _from_address(server.url, "127.0.0.4", {"user": "bob", "password": PEOPLE["bob"][2]})
    assert status == 200  # bob at his own console is not locked out


def test_an_observer_may_read_procedures_but_not_save_them(server: WebServer) -> None:
    client = Client(server.url)
    assert client.sign_in("carol")[0] == 200
    status, document, _ = client.call("GET", "/api/author/procedures/web_walkthrough.xml")
    assert status == 200 and document["attrs"]["id"] == "web_walkthrough"
    status, body, _ = client.act("/api/author/save", {"name": "carol_was_here.xml", "document": document})
    assert status == 403 and "observer" in body["error"]
    assert not (server.procedures / "carol_was_here.xml").exists()
    for name in ("..%2Fsecret.xml", "secret.xml"):  # only files the procedures directory lists
        status, body, _ = client.call("GET", f"/api/author/procedures/{name}")
        assert status in (400, 404), body


def test_serving_beyond_loopback_needs_tls_unless_told_otherwise(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["--address", "0.0.0.0", "--port", "0", "--db", f"sqlite:///{tmp_path / 'a.db'}"]) == 2
    assert "give --certfile and --keyfile (TLS), or --insecure" in capsys.readouterr().err
    assert main(["--certfile", str(tmp_path / "missing.pem"), "--port", "0"]) == 2
    assert "--certfile and --keyfile go together" in capsys.readouterr().err
    junk = tmp_path / "junk.pem"
    junk.write_text("not a certificate\n")
    assert main(["--certfile", str(junk), "--keyfile", str(junk), "--port", "0"]) == 2
    assert "not a usable PEM certificate and key" in capsys.readouterr().err


def test_sysrep_folders_are_read_as_one_and_an_id_declared_twice_refuses_to_serve(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    again = tmp_path / "again"
    again.mkdir()
    (again / "cdra_copy.yaml").write_text((REPO / "sysrep" / "cdra.yaml").read_text())
    assert main(["--sysreps", str(REPO / "sysrep"), "--sysreps", str(again), "--port", "0"]) == 2
    said = capsys.readouterr().err
    assert "duplicate SysRep id 'cdra'" in said and "cdra_copy.yaml" in said
    assert str(REPO / "sysrep" / "cdra.yaml") in said  # both files named


def test_rosbridge_urls_and_cameras_are_given_per_binding_and_checked(capsys: pytest.CaptureFixture[str]) -> None:
    for option, said in (
        (
            ["--rosbridge", "iva.yaml=http://127.0.0.1:9090"],
            "--rosbridge iva.yaml=http://127.0.0.1:9090: expected [BINDING=]ws://HOST:PORT or wss://HOST:PORT",
        ),
        (
            ["--rosbridge", "ws://a:1", "--rosbridge", "ws://b:2"],
            "--rosbridge ws://b:2: every binding was given one already",
        ),
        (["--camera", "eva.yaml=ee camera"], "--camera eva.yaml=ee camera: expected [BINDING=]NAME"),
        (
            ["--camera", "iva.yaml=scene", "--camera", "iva.yaml=ee_camera"],
            "--camera iva.yaml=ee_camera: binding iva.yaml was given one already",
        ),
    ):
        assert main([*option, "--port", "0"]) == 2, option
        assert said in capsys.readouterr().err


def test_a_binding_without_its_own_camera_has_the_one_given_for_every_binding() -> None:
    cameras = CameraSettings({"iva.yaml": "scene", "": "ee_camera"})
    assert (cameras.camera_for("iva.yaml"), cameras.camera_for("eva.yaml")) == ("scene", "ee_camera")
    assert CameraSettings({"iva.yaml": "scene"}).camera_for("eva.yaml") is None


def test_with_a_certificate_the_view_is_served_over_tls_with_secure_cookies(tmp_path: Path) -> None:
    cert, key = self_signed_certificate(tmp_path)
    db = tmp_path / "ground.db"
    store = AccountStore(f"sqlite:///{db}")
    store.add("alice", "operator", PEOPLE["alice"][2])
    store.close()
    served = caretaker(
        "serve",
        "--port",
        "0",
        "--db",
        f"sqlite:///{db}",
        "--certfile",
        str(cert),
        "--keyfile",
        str(key),
        "--procedures",
        str(REPO / "procedures"),
        "--reports",
        str(tmp_path / "reports"),
        env=dict(os.environ),
        name="serve-tls",
    )
    try:
        url = served.wait_ready(90).split()[-1]
        assert url.startswith("https://127.0.0.1:")
        client = Client(url, context=ssl.create_default_context(cafile=str(cert)))
        status, _, headers = client.sign_in("alice")
        assert status == 200 and "secure" in headers["set-cookie"].lower()
        with pytest.raises((urllib.error.URLError, ConnectionError, http.client.HTTPException)):  # no plain http there
            urllib.request.urlopen(url.replace("https://", "http://") + "/api/session", timeout=30)
    finally:
        served.stop()


def test_demo_serve_gives_its_operator_a_new_password_each_time(tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'demo.db'}"  # a fresh database: nobody could sign in to the web view
    first = demo_operator(db)
    second = demo_operator(db)  # the next demo --serve on the same database
    store = AccountStore(db)
    try:
        account = store.verify(DEMO_USER, second)
        assert account is not None and account.may_act
        assert first != second and store.verify(DEMO_USER, first) is None
        assert [a.user for a in store.accounts()] == [DEMO_USER]
    finally:
        store.close()


def test_a_demo_run_is_approved_by_a_second_operator_account_of_its_own(tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'demo.db'}"
    operator = demo_operator(db)
    first = demo_approver(db)
    second = demo_approver(db)  # the next demo on the same database: a new password, the same account
    store = AccountStore(db)
    try:
        approver = store.verify(DEMO_APPROVER, second)
        assert approver is not None and approver.may_act  # an operator: an observer may not approve
        assert first != second and store.verify(DEMO_APPROVER, first) is None
        assert store.verify(DEMO_USER, operator) is not None  # the signed-in operator's account untouched
        assert sorted(a.user for a in store.accounts()) == sorted([DEMO_USER, DEMO_APPROVER])
    finally:
        store.close()
