"""The suite against another server, the Rust ``rosbridge-server-rs`` (run as bench/ runs it):
it completes without a crash or a hang and gives every case an outcome and its frames. Which
outcomes the peer gets is its own business (docs/interop.md reads them)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from caretaker.processes import REPO
from interop.catalog import DEFAULT_PROFILES

from .suite_support import assert_complete, finish_suite, start_suite

sys.path.insert(0, str(REPO))  # bench/ is a folder of scripts, not an installed package
from bench.rosbridge_bench import start_rust, stop

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=70)]


def test_the_suite_completes_against_rosbridge_server_rs(ros_env: dict[str, str], tmp_path: Path) -> None:
    server, port = start_rust(dict(ros_env), tmp_path)
    try:
        run = finish_suite(
            start_suite(f"ws://127.0.0.1:{port}", tmp_path / "report", "rosbridge-server-rs", env=dict(os.environ)),
            tmp_path / "report",
            "rosbridge-server-rs",
            timeout=240,
        )
        assert server.poll() is None, "the Rust server died during the suite"
    finally:
        stop(server)
    assert run.returncode in (0, 1), run.output[-2000:]
    assert_complete(run, DEFAULT_PROFILES)
    page = (tmp_path / "report" / "index.html").read_text()
    for case in run.cases:
        assert f"#s0-{case.replace('.', '-')}'" in page and f"id='s0-{case.replace('.', '-')}'" in page, case
    assert "Traceback" not in run.output
