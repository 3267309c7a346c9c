"""Child processes of the stack launcher and the tests: await readiness, always stop them.

Long-running Caretaker processes print ``READY <what>`` on stdout once they serve
(docs/interfaces.md), so launchers wait on that event instead of sleeping. Each child runs in
its own process group (Ctrl-C reaches it through us, and stopping it stops its children) and is
killed by the kernel if this process dies first, so a crashed launcher leaves no orphans.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
VENV_BIN = REPO / ".venv" / "bin"
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """In the child before exec: get SIGTERM when the parent dies (Linux prctl).

    The kernel ties this to the *thread* that forked, so start children from a thread that
    outlives them (the main thread, in the launcher and in tests).
    """
    import ctypes

    ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


class ProcessFailed(RuntimeError):
    """A managed process exited or did not become ready; the message carries its last output."""


class ManagedProcess:
    """A child process in its own process group, with its output kept for error messages."""

    def __init__(
        self,
        argv: list[str],
        env: dict[str, str],
        name: str | None = None,
        *,
        on_line: Callable[[str, str], None] | None = None,
    ) -> None:
        """Start ``argv``; ``on_line(name, line)`` is called for every line it prints."""
        self.argv = argv
        self._on_line = on_line
        self.name = name or Path(argv[0]).name
        self.output: deque[str] = deque(maxlen=400)
        self.printed = 0  # lines printed so far (``output`` keeps the last 400)
        self._output_changed = threading.Condition()
        self._ended = False
        self.proc = subprocess.Popen(
            argv,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
            start_new_session=True,
            preexec_fn=_die_with_parent,
        )
        self._reader = threading.Thread(target=self._read, name=f"{self.name}-output", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            line = raw.rstrip("\n")
            with self._output_changed:
                self.output.append(line)
                self.printed += 1
                self._output_changed.notify_all()
            if self._on_line is not None:
                self._on_line(self.name, line)
        self.proc.stdout.close()  # the child is gone; its pipe is ours to close
        with self._output_changed:
            self._ended = True
            self._output_changed.notify_all()

    def tail(self, lines: int = 60) -> str:
        """The last ``lines`` lines the process printed."""
        with self._output_changed:
            return "\n".join(list(self.output)[-lines:])

    def wait_for_line(self, pattern: str, timeout: float = 60.0, *, after: int = 0) -> str:
        """Block until the process printed a line matching ``pattern`` (a regex); return that line.
        ``after``: only a line printed after the first ``after`` lines (a value of :attr:`printed`).

        Raises:
            ProcessFailed: the process ended, or ``timeout`` passed, without printing one.
        """
        regex = re.compile(pattern)
        found: list[str] = []

        def printed() -> bool:
            first = self.printed - len(self.output)  # the number of the oldest line kept
            lines = enumerate(self.output, first)
            found[:] = [line for number, line in lines if number >= after and regex.search(line)][:1]
            return bool(found) or self._ended

        with self._output_changed:
            self._output_changed.wait_for(printed, timeout)
        if not found:
            state = self.how_it_ended() if self._ended else f"printed no line matching {pattern!r} in {timeout} s"
            raise ProcessFailed(f"{self.name} {state}; its output:\n{self.tail()}")
        return found[0]

    def how_it_ended(self, patience: float = 5.0) -> str:
        """In words, once its output has closed: the exit code, or the signal that killed it.

        The output closes a moment before the process is reaped, so the code is waited for
        (briefly) rather than polled, which would read "None".
        """
        try:
            code = self.proc.wait(patience)
        except subprocess.TimeoutExpired:
            return f"closed its output but was still running {patience} s later"
        if code < 0:
            try:
                return f"was killed by {signal.Signals(-code).name}"
            except ValueError:
                return f"was killed by signal {-code}"
        return f"exited with code {code}"

    def wait_ready(self, timeout: float = 60.0) -> str:
        """Block until the process printed its READY line (returned); raise ProcessFailed otherwise."""
        return self.wait_for_line(r"^READY\b", timeout)

    @property
    def running(self) -> bool:
        return self.proc.poll() is None

    def kill(self) -> None:
        """Kill the whole process group at once (a crash, for fault tests)."""
        if self.running:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)

    def stop(self, timeout: float = 10.0) -> int | None:
        """Ctrl-C the process group, then SIGKILL what is left after ``timeout``."""
        if self.running:
            try:
                os.killpg(self.proc.pid, signal.SIGINT)
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout)
            except ProcessLookupError:
                pass
        self._reader.join(timeout)
        return self.proc.returncode


def caretaker(
    *args: str, env: dict[str, str], name: str | None = None, on_line: Callable[[str, str], None] | None = None
) -> ManagedProcess:
    """Start ``caretaker ARGS...`` from the venv."""
    return ManagedProcess(
        [str(VENV_BIN / "caretaker"), *args], env, name or (args[0] if args else "caretaker"), on_line=on_line
    )


def python(*args: str, env: dict[str, str], name: str | None = None) -> ManagedProcess:
    """Start ``python ARGS...`` with this interpreter (the venv's)."""
    return ManagedProcess([sys.executable, *args], env, name)
