"""The bridge on a long, lossy link (issue 15): keepalive that rides out outages, and every
quota documented with its option."""

from __future__ import annotations

import dataclasses
import re
import struct
from pathlib import Path

from bridge.rosbridge.limits import Limits, option
from bridge.rosbridge.server import parse_args
from support.processes import caretaker

from .rosbridge_support import CLOSE, PING, FrameSocket, bridge_url

DOCS = Path(__file__).resolve().parents[2] / "docs" / "rosbridge.md"


def test_keepalive_defaults_outlast_a_link_outage() -> None:
    args = parse_args([])
    # a 30 s outage plus TCP's retransmission back-off and a 2.6 s round trip stay within it
    assert (args.ping_interval, args.ping_timeout) == (30.0, 180.0)
    assert parse_args(["--ping-interval", "0", "--ping-timeout", "300"]).ping_timeout == 300.0


def test_a_peer_that_stops_answering_pings_is_closed_with_1011(ros_env: dict[str, str]) -> None:
    process = caretaker("bridge", "--port", "0", "--ping-interval", "0.2", "--ping-timeout", "0.5", env=ros_env)
    try:
        process.wait_ready(60)
        host, port = bridge_url(process).split("//")[1].rsplit(":", 1)
        silent = FrameSocket(host, int(port))  # reads, but never answers a ping
        opcodes = []
        while not opcodes or opcodes[-1][0] != CLOSE:
            opcodes.append(silent.read_frame())
        assert opcodes[0][0] == PING and struct.unpack("!H", opcodes[-1][1][:2])[0] == 1011
        silent.close()
    finally:
        process.stop()


def test_every_limit_is_documented_with_its_default() -> None:
    table = DOCS.read_text()
    for item in dataclasses.fields(Limits):
        row = re.search(rf"^\| `{option(item.name)} N` \| ([^|]+) \|", table, re.MULTILINE)
        assert row, f"{option(item.name)} is not in docs/rosbridge.md's limits table"
        assert row.group(1).strip() == documented(item.default), f"{option(item.name)}: the docs say {row.group(1)}"


def documented(default: float) -> str:
    """How the limits table spells a default: seconds, MiB, or a plain count."""
    if isinstance(default, float):
        return f"{default:g} s"
    if default >= 2**20 and default % 2**20 == 0:
        return f"{default // 2**20} MiB"
    return f"{default:,}"
