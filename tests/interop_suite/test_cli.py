"""``caretaker interop``'s own checks: bad arguments and an unreachable server exit 2 with a
message saying what to fix, and the report never carries a server's text unescaped."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from interop.cli import main
from interop.outcome import CaseResult, Frame, Outcome
from interop.report import passed, write_report


def _closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]  # nothing listens once the socket is closed


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["http://127.0.0.1:9090"], "not a ws:// or wss:// URL"),
        (["ws://127.0.0.1:9090", "--profile", "core,nonsense"], "unknown profile 'nonsense'"),
        (["ws://127.0.0.1:9090", "--profile", "auth"], "the auth profile needs --secret-file"),
        (["ws://127.0.0.1:9090", "--ca", "ca.pem"], "--ca is for wss:// servers"),
        (["ws://127.0.0.1:9090", "--quiet", "600"], "--quiet 1-60 s"),
    ],
)
def test_bad_arguments_exit_2_saying_why(argv: list[str], says: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    assert says in capsys.readouterr().err


def test_an_empty_secret_file_is_named_with_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    secret = tmp_path / "secret"
    secret.write_text("\n")
    assert main(["ws://127.0.0.1:9090", "--secret-file", str(secret)]) == 2
    assert f"{secret}:1: the secret file is empty" in capsys.readouterr().err


def test_an_unreachable_server_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    url = f"ws://127.0.0.1:{_closed_port()}"
    assert main([url, "--profile", "core"]) == 2
    assert f"cannot open a WebSocket to {url}" in capsys.readouterr().err


def _result(case: str, profile: str, outcome: Outcome, observed: str = "seen") -> CaseResult:
    frames = (Frame("received", 0.1, observed, "A"),)
    return CaseResult(case, "a title", ("P-GEN-1",), outcome, "expected", observed, 0.2, frames, {"profile": profile})


def test_the_report_escapes_what_a_server_said_and_keeps_other_servers(tmp_path: Path) -> None:
    hostile = "<script>alert(1)</script>"
    write_report(tmp_path, "first", [_result("core.1", "core", Outcome.OK)])
    write_report(tmp_path, hostile, [_result("core.1", "core", Outcome.FAILED, hostile)])
    page = (tmp_path / "index.html").read_text()
    assert hostile not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert "href='#s0-core-1'" in page and "href='#s1-core-1'" in page  # both servers' columns


def test_only_claimed_profiles_decide_the_verdict() -> None:
    results = [_result("core.1", "core", Outcome.NON_STRICT), _result("auth.1", "auth", Outcome.FAILED)]
    assert passed(results, ["core"])
    assert not passed(results, ["core", "auth"])
    assert not passed([_result("core.2", "core", Outcome.UNIMPLEMENTED)], ["core"])
