"""An operator at a real terminal: a process on a pseudo-terminal, read and answered by a test.

``caretaker run`` asks its operator questions only on a TTY (retry, skip, done...), so fault
tests that need an operator's decision drive it through a pty, as a person at a console would.
"""

from __future__ import annotations

import os
import pty
import re
import signal
import subprocess
import threading


class TerminalSession:
    """A child process whose stdin/stdout/stderr are one pseudo-terminal."""

    def __init__(self, argv: list[str], env: dict[str, str]) -> None:
        self._master, slave = pty.openpty()
        self.proc = subprocess.Popen(
            argv, env=env, stdin=slave, stdout=slave, stderr=slave, start_new_session=True, close_fds=True
        )
        os.close(slave)
        self._text = ""
        self._seen = 0  # everything before this offset has been matched by expect()
        self._changed = threading.Condition()
        threading.Thread(target=self._read, name="pty-reader", daemon=True).start()

    def _read(self) -> None:
        while True:
            try:
                chunk = os.read(self._master, 4096)
            except OSError:
                chunk = b""
            with self._changed:
                if not chunk:
                    self._text += "\n<EOF>"
                    self._changed.notify_all()
                    return
                self._text += chunk.decode(errors="replace").replace("\r\n", "\n")
                self._changed.notify_all()

    @property
    def text(self) -> str:
        with self._changed:
            return self._text

    def expect(self, pattern: str, timeout: float = 120.0) -> re.Match[str]:
        """Wait until ``pattern`` appears in output not matched before; return the match."""
        regex = re.compile(pattern)
        with self._changed:
            found: list[re.Match[str]] = []

            def appeared() -> bool:
                match = regex.search(self._text, self._seen)
                if match:
                    found.append(match)
                return bool(match) or self._text.endswith("<EOF>")

            if not self._changed.wait_for(appeared, timeout) or not found:
                raise AssertionError(f"{pattern!r} did not appear; the terminal shows:\n{self._text[-3000:]}")
            self._seen = found[0].end()
            return found[0]

    def send(self, line: str) -> None:
        """Type ``line`` and Enter."""
        os.write(self._master, (line + "\n").encode())

    def close(self, timeout: float = 30.0) -> int:
        """Wait for the process to end (Ctrl-C, then kill, if it does not); return its exit code. Idempotent."""
        if self._master < 0:
            return self.proc.wait()
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                return self.proc.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                return self.proc.wait(10)
        finally:
            os.close(self._master)
            self._master = -1
