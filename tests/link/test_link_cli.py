"""``caretaker link`` as a ground team runs it: READY line, control socket, one-line errors."""

from __future__ import annotations

import re
import socket
import socketserver
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from caretaker.link import LinkControl
from caretaker.processes import VENV_BIN
from support.processes import COMMAND_HANG_S, caretaker


class _Echo(socketserver.BaseRequestHandler):
    def handle(self) -> None:
        while data := self.request.recv(65536):
            self.request.sendall(data)


@pytest.fixture
def echo_port() -> Iterator[int]:
    """A threaded TCP echo server on loopback (the habitat side the link connects to)."""
    with socketserver.ThreadingTCPServer(("127.0.0.1", 0), _Echo) as server:
        server.daemon_threads = True
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        yield server.server_address[1]
        server.shutdown()


def test_link_command_relays_with_delay_and_reports_through_its_control_socket(
    echo_port: int, tmp_path: Path, ros_env: dict[str, str]
) -> None:
    control_path = tmp_path / "link.sock"
    link = caretaker(
        "link",
        "--listen",
        "127.0.0.1:0",
        "--to",
        f"127.0.0.1:{echo_port}",
        "--delay",
        "0.1",
        "--jitter",
        "0.02",
        "--loss",
        "2%",
        "--down-kbps",
        "64",
        "--up-kbps",
        "16",
        "--seed",
        "7",
        "--outage",
        "hold:0.5@0",
        "--control",
        str(control_path),
        env=ros_env,
    )
    try:
        ready = link.wait_ready(30)
        match = re.match(r"READY link 127\.0\.0\.1:(\d+) -> 127\.0\.0\.1:(\d+) \((.*)\) control (\S+)$", ready)
        assert match, ready
        assert int(match[2]) == echo_port and match[4] == str(control_path)
        assert "loss 2%" in match[3] and "16 kbit/s" in match[3] and "outage hold:0.5@0" in match[3]
        start = time.monotonic()
        with socket.create_connection(("127.0.0.1", int(match[1])), timeout=30) as sock:
            sock.sendall(b"hello habitat")
            assert sock.recv(100) == b"hello habitat"
            assert time.monotonic() - start >= 0.4  # handshake and echo at 0.1 s each way
            stats = LinkControl(control_path).stats()
        assert (stats.up_bytes, stats.down_bytes, stats.holds) == (13, 13, 1)
    finally:
        assert link.stop() == 0, link.tail()
    assert not control_path.exists()
    assert "stopped: 13 bytes up, 13 bytes down, 1 connection(s)" in link.tail()


@pytest.mark.parametrize(
    "options, complaint",
    [
        (["--delay", "-1"], "--delay -1.0: expected a number >= 0"),
        (["--loss", "1.5"], "--loss 1.5: expected a number >= 0 and < 1"),
        (["--loss", "lots"], "'lots' is not a fraction (0.05) or a percentage (5%)"),
        (["--up-kbps", "0"], "--up-kbps/--down-kbps 0.0: expected a bit rate > 0"),
        (["--outage", "pause:1@2"], "--outage 'pause:1@2': expected KIND:SECONDS@START"),
        (["--to", "habitat"], "--to 'habitat': expected HOST:PORT"),
        (["--seed", "x"], "argument --seed: invalid int value: 'x'"),
        (["--bogus"], "unrecognized arguments: --bogus"),
    ],
)
def test_bad_options_give_one_line_that_names_them(options: list[str], complaint: str) -> None:
    result = subprocess.run(
        [str(VENV_BIN / "caretaker"), "link", *options], capture_output=True, text=True, timeout=COMMAND_HANG_S
    )
    assert result.returncode == 2
    assert result.stdout == ""
    assert result.stderr.count("\n") == 1 and complaint in result.stderr, result.stderr


def test_an_address_in_use_or_a_bad_control_path_is_reported(tmp_path: Path) -> None:
    plain = tmp_path / "plain"
    plain.write_text("")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        for options, complaint in [
            (["--listen", f"127.0.0.1:{port}"], "address already in use"),
            (["--listen", "127.0.0.1:0", "--control", str(plain)], "is not a socket"),
        ]:
            result = subprocess.run(
                [str(VENV_BIN / "caretaker"), "link", *options], capture_output=True, text=True, timeout=60
            )
            assert result.returncode == 1
            assert complaint in result.stderr and "Traceback" not in result.stderr, result.stderr
            assert "READY" not in result.stdout
