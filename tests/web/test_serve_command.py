"""``caretaker serve`` itself: loopback by default, clear errors, nothing served without sign-in."""

from __future__ import annotations

import http.cookiejar
import json
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import websockets
from websockets.sync.client import connect

from pride.web.accounts import AccountsError, Role, load_accounts
from pride.web.server import main

EXAMPLE = Path(__file__).resolve().parents[2] / "python" / "pride" / "web" / "accounts.example.yaml"


def _request(url: str, body: dict | None = None) -> tuple[int, dict]:
    data = json.dumps(body).encode() if body is not None else None
    request = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as error:
        return error.code, json.loads(error.read())


def test_the_example_accounts_have_both_roles() -> None:
    accounts = load_accounts(EXAMPLE)
    assert accounts["alice"].role is Role.OPERATOR and accounts["alice"].may_act
    assert accounts["carol"].role is Role.OBSERVER and not accounts["carol"].may_act


@pytest.mark.parametrize(("text", "message"), [
    ("users: []\n", "expected a top-level 'accounts:' list"),
    ("accounts:\n- {user: dave, role: admin}\n", "accounts entry 1 (dave): 'role' must be one of operator, observer (got 'admin')"),
    ("accounts:\n- {user: 'a b', role: operator}\n", "'user' must be 1-64 letters"),
    ("accounts:\n- {user: x, role: operator}\n- {user: x, role: observer}\n", "accounts entry 2: user 'x' is listed twice"),
    ("accounts:\n- {user: x, role: operator, password: p}\n", "unknown key(s) password"),
    ("accounts: [\n", "not valid YAML"),
])
def test_malformed_accounts_files_say_what_to_fix(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "accounts.yaml"
    path.write_text(text)
    with pytest.raises(AccountsError) as caught:
        load_accounts(path)
    assert str(caught.value).startswith(str(path)) and message in str(caught.value)


def test_serve_refuses_to_start_with_a_bad_accounts_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "accounts.yaml"
    path.write_text("accounts:\n- {user: dave, role: admin}\n")
    assert main(["--accounts", str(path), "--port", "0"]) == 2
    assert "'role' must be one of operator, observer" in capsys.readouterr().err


def test_serve_binds_loopback_and_serves_nothing_before_sign_in(server) -> None:
    assert server.url.startswith("http://127.0.0.1:")
    status, body = _request(f"{server.url}/api/runs")
    assert (status, body["error"]) == (401, "sign in first")
    status, body = _request(f"{server.url}/api/session", {"user": "mallory"})
    assert status == 403 and "no account 'mallory'" in body["error"]

    ws_url = server.url.replace("http://", "ws://") + "/ws/runs/anything"
    with pytest.raises(websockets.InvalidStatus) as refused:  # closed before the handshake completes
        connect(ws_url, open_timeout=30)
    assert refused.value.response.status_code == 403


def test_an_observer_may_read_procedures_but_not_save_them(server) -> None:
    jar = http.cookiejar.CookieJar()
    opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(jar))

    def call(path: str, body: dict | None = None) -> tuple[int, dict]:
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(server.url + path, data=data, headers={"Content-Type": "application/json"})
        try:
            with opener.open(request, timeout=30) as response:
                return response.status, json.loads(response.read())
        except urllib.error.HTTPError as error:
            text = error.read()
            return error.code, json.loads(text) if text.startswith(b"{") else {"error": text.decode()}

    assert call("/api/session", {"user": "carol"})[0] == 200
    status, document = call("/api/author/procedures/web_walkthrough.xml")
    assert status == 200 and document["attrs"]["id"] == "web_walkthrough"
    status, body = call("/api/author/save", {"name": "carol_was_here.xml", "document": document})
    assert status == 403 and "observer" in body["error"]
    assert not (server.procedures / "carol_was_here.xml").exists()
    for name in ("..%2Fsecret.xml", "secret.xml"):  # only files the procedures directory lists
        status, body = call(f"/api/author/procedures/{name}")
        assert status in (400, 404), body
