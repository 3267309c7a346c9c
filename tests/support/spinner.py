"""A test client's executor spun on its own thread, and stopped without racing it.

``threading.Thread(target=executor.spin)`` followed by ``executor.shutdown()`` races: shutdown
destroys the executor's guard condition while the spinning thread may still be between two
callbacks, and that thread then dies with ``InvalidHandle`` inside whichever test runs next on
the worker. Here the thread is told to stop, woken, and joined first; only then is the executor
shut down.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from rclpy.executors import Executor
from rclpy.node import Node

__all__ = ["Spinner"]


class Spinner:
    """Spins ``executor`` (which serves ``node``) on a daemon thread until :meth:`stop`.

    ``on_error`` hears an exception a callback raised (the thread then stops), so a test waiting
    on a topic can report it instead of stalling to its timeout.
    """

    def __init__(
        self, executor: Executor, node: Node, *, name: str, on_error: Callable[[BaseException], None] | None = None
    ) -> None:
        self._executor = executor
        self._stopping = threading.Event()
        self._wake = node.create_guard_condition(lambda: None)
        self._on_error = on_error
        self._thread = threading.Thread(target=self._spin, name=name, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            while not self._stopping.is_set() and self._executor.context.ok():
                self._executor.spin_once()
        except BaseException as exc:
            if self._on_error is None:
                raise
            self._on_error(exc)

    def stop(self, timeout: float = 10.0) -> None:
        """Stop spinning, wait for the thread, then shut the executor down."""
        self._stopping.set()
        self._wake.trigger()
        self._thread.join(timeout)
        if self._thread.is_alive():
            raise RuntimeError(f"{self._thread.name} did not stop within {timeout} s")
        self._executor.shutdown()
