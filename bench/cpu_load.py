"""CPU hogs beside any command: how Caretaker is tried on a machine that is not idle.

Usage: .venv/bin/python bench/cpu_load.py [--hogs N] -- COMMAND [ARG...]
       (e.g. ``-- .venv/bin/pytest tests/web/test_web_on_real_stack.py``, ``-- .venv/bin/caretaker demo iva``)

A hog is a separate process at nice 0 (the same priority as what it competes with) that spins
in pure Python until it is stopped; the default is one per core, so every core is contended.
The command's exit status is returned; the hogs are stopped however it ends. Importable:
:func:`cpu_hogs` is a context manager for scripts that measure beside load (bench/demo_under_load.py).
"""

from __future__ import annotations

import argparse
import ctypes
import multiprocessing
import multiprocessing.synchronize
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["cpu_hogs", "main"]

_PR_SET_PDEATHSIG = 1


def _spin(stop: multiprocessing.synchronize.Event) -> None:
    # Killed with its parent however the parent ends (a benchmark killed mid-run leaves no hog).
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    os.setpriority(os.PRIO_PROCESS, 0, 0)  # nice 0 whatever the parent's niceness
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops it, not the terminal's Ctrl-C
    x = 0
    while not stop.is_set():
        for _ in range(100_000):  # check the flag rarely: the point is to burn the core
            x = (x * 1103515245 + 12345) & 0x7FFFFFFF


@contextmanager
def cpu_hogs(count: int | None = None) -> Iterator[list[int]]:
    """``count`` busy processes (default: one per core) for the duration of the block; their pids."""
    if count is None:
        count = os.cpu_count() or 1
    context = multiprocessing.get_context("spawn")  # no copy of the caller's threads or ROS state
    stop = context.Event()
    hogs = [context.Process(target=_spin, args=(stop,), name=f"cpu-hog-{i}", daemon=True) for i in range(count)]
    for hog in hogs:
        hog.start()
    try:
        yield [hog.pid for hog in hogs if hog.pid is not None]
    finally:
        stop.set()
        for hog in hogs:
            hog.join(5.0)
            if hog.is_alive():
                hog.kill()
                hog.join()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench/cpu_load.py", description=__doc__.splitlines()[0])
    parser.add_argument("--hogs", type=int, default=os.cpu_count() or 1, help="busy processes (default: one per core)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command to run beside them (after --)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("name the command to run after --")
    if args.hogs < 0:
        parser.error(f"--hogs must be >= 0, got {args.hogs}")
    with cpu_hogs(args.hogs) as pids:
        print(
            f"cpu_load: {len(pids)} hogs (pids {', '.join(map(str, pids))}) beside: {' '.join(command)}",
            file=sys.stderr,
            flush=True,
        )
        try:
            return subprocess.call(command)
        except FileNotFoundError:
            print(f"cpu_load: no such command: {command[0]}", file=sys.stderr)
            return 127
        except KeyboardInterrupt:
            return 130


if __name__ == "__main__":
    sys.exit(main())
