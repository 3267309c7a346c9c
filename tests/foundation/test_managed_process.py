"""ManagedProcess: a part that ends before its READY line says how it ended, in words; echoed lines name their part."""

from __future__ import annotations

import io
import os
import sys

import pytest

from caretaker.processes import ManagedProcess, ProcessFailed
from caretaker.stack import PARTS, PartEcho
from caretaker.terminal import TerminalLines


def test_an_exit_before_the_line_names_its_code_never_none() -> None:
    # the output closes, then the process lingers a moment before it exits
    script = (
        "import os, sys, time; print('starting'); sys.stdout.flush(); "
        "os.close(1); os.close(2); time.sleep(0.3); sys.exit(3)"
    )
    part = ManagedProcess([sys.executable, "-c", script], dict(os.environ), "part")
    with pytest.raises(ProcessFailed, match=r"part exited with code 3; its output:\n.*starting"):
        part.wait_ready(30)


def test_a_part_killed_by_a_signal_says_which() -> None:
    part = ManagedProcess(
        [sys.executable, "-c", "import os, signal; os.kill(os.getpid(), signal.SIGKILL)"], dict(os.environ)
    )
    with pytest.raises(ProcessFailed, match=r"was killed by SIGKILL"):
        part.wait_ready(30)


def test_echoed_lines_say_which_part_printed_them_in_one_column() -> None:
    stream = io.StringIO()
    echo = PartEcho([part.name for part in PARTS], TerminalLines(stream), everything=True)
    said = {"sim": ["world loaded", "READY sim"], "at-server": ["restored nothing", "READY at-server"]}
    for name, lines in said.items():
        script = "; ".join(f"print({line!r})" for line in lines)
        part = ManagedProcess([sys.executable, "-c", script], dict(os.environ), name, on_line=echo)
        assert part.proc.wait(30) == 0
        part.stop()  # joins the reader: every line has been echoed
    # the longest part name (perception) sets the column every line starts in
    assert stream.getvalue().splitlines() == [
        "[sim]        world loaded",
        "[sim]        READY sim",
        "[at-server]  restored nothing",
        "[at-server]  READY at-server",
    ]


def test_unechoed_parts_still_show_their_security_events() -> None:
    stream = io.StringIO()
    echo = PartEcho([part.name for part in PARTS], TerminalLines(stream), everything=False)
    for line in ("READY onboard", "SECURITY unit 0123456789ab refused: forged", "an ordinary line"):
        echo("onboard", line)
    assert stream.getvalue().splitlines() == ["[onboard]    SECURITY unit 0123456789ab refused: forged"]
