"""The ``caretaker`` command itself: what every subcommand shares."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest


def _blocked_in_fifo_open(pid: int) -> bool:
    """Whether the kernel has the process waiting for a writer to open the FIFO."""
    try:
        return Path(f"/proc/{pid}/wchan").read_text() == "wait_for_partner"
    except OSError:  # gone
        return False


def test_an_interrupt_ends_a_command_with_a_line_not_a_traceback(tmp_path: Path) -> None:
    """SIGINT where a command has no handler of its own (here: opening a file nobody writes yet,
    as a supervisor stopping a run while it closes): exit 130 and one line saying so."""
    fifo = tmp_path / "procedure.xml"
    os.mkfifo(fifo)
    # SIGINT at its default whatever this test run inherited: a shell starts background jobs with it
    # ignored, and Python then keeps ignoring it, as it should.
    started = ["env", "--default-signal=INT", sys.executable, "-m", "caretaker.cli", "check", str(fifo)]
    with subprocess.Popen(started, stderr=subprocess.PIPE, text=True) as command:
        try:
            while not _blocked_in_fifo_open(command.pid):  # the kernel says where it waits: no timing guess
                if command.poll() is not None:
                    pytest.fail(f"caretaker check ended before it opened the file: {command.communicate()[1]}")
                time.sleep(0.01)
            command.send_signal(signal.SIGINT)
            _, stderr = command.communicate(timeout=60)
        finally:
            command.kill()
    assert command.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert stderr.strip().splitlines()[-1] == "caretaker check: interrupted"
