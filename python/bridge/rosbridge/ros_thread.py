"""ROS 2 side of the bridge: rclpy on dedicated threads, and the one hand-off to asyncio.

Threads and their jobs:

* ``ros-events``: an ``EventsExecutor`` turned by ``spin_once`` in a loop (``spin()`` does not
  work in the Jazzy 7.1.6 wheels).  It serves the hot paths on :attr:`RosThread.node`:
  subscriptions and service *clients*.  It was about 5x faster than the default executor.
* ``ros-servers``: a ``SingleThreadedExecutor`` for :attr:`RosThread.server_node`, which holds
  entities whose callbacks must wait for a WebSocket client (services and actions that a
  client serves, action clients).  They need coroutine callbacks, which the EventsExecutor
  does not run.
* the asyncio thread owns every WebSocket and all per-connection state.

Entity creation, publishing and ``call_async`` are thread-safe in rclpy, so the asyncio side
calls them directly.  Everything flowing from ROS back to asyncio goes through
:meth:`RosThread.deliver`, which batches callbacks into the event loop with at most one
pending wake-up, so a burst of messages costs one ``call_soon_threadsafe``.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections import deque
from typing import Any, Callable

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.signals import SignalHandlerOptions

log = logging.getLogger(__name__)

NODE_NAME = "rosbridge_websocket"


class RosThread:
    """rclpy context, the bridge's nodes, and the threads that spin them."""

    def __init__(self, loop: asyncio.AbstractEventLoop, node_name: str = NODE_NAME) -> None:
        self.loop = loop
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(node_name, context=self.context)
        self.server_node = rclpy.create_node(f"{node_name}_servers", context=self.context)
        self._events = EventsExecutor(context=self.context)
        self._events.add_node(self.node)
        self.server_executor = SingleThreadedExecutor(context=self.context)
        self.server_executor.add_node(self.server_node)
        self._inbox: deque[tuple[Callable[..., Any], tuple[Any, ...]]] = deque()
        self._drain_scheduled = False
        self._running = True
        self._threads = [
            threading.Thread(target=self._spin, args=(self._events,), name="ros-events", daemon=True),
            threading.Thread(target=self._spin, args=(self.server_executor,), name="ros-servers", daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    def deliver(self, callback: Callable[..., Any], *args: Any) -> None:
        """Run ``callback(*args)`` on the asyncio thread, in order (call from any ROS thread)."""
        self._inbox.append((callback, args))
        if not self._drain_scheduled:
            self._drain_scheduled = True
            try:
                self.loop.call_soon_threadsafe(self._drain)
            except RuntimeError:  # the loop closed during shutdown: nobody is left to tell
                pass

    def wrap(self, ros_future: Any) -> asyncio.Future[Any]:
        """An asyncio future (of the event loop) settled when the rclpy ``ros_future`` is."""
        answer: asyncio.Future[Any] = self.loop.create_future()
        ros_future.add_done_callback(lambda done: self.deliver(_settle, answer, done))
        return answer

    def _drain(self) -> None:
        # Clear the flag before emptying, so an item appended meanwhile schedules a new drain.
        self._drain_scheduled = False
        inbox = self._inbox
        while inbox:
            callback, args = inbox.popleft()
            try:
                callback(*args)
            except Exception:
                log.exception("delivering %s from ROS failed", getattr(callback, "__qualname__", callback))

    def _spin(self, executor: Any) -> None:
        while self._running and self.context.ok():
            try:
                executor.spin_once(timeout_sec=0.2)
            except Exception:
                if self._running:
                    log.exception("a ROS callback failed")

    def shutdown(self) -> None:
        """Stop the threads and tear down nodes and context (idempotent)."""
        if not self._running:
            return
        self._running = False
        self.server_executor.wake()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._events.shutdown()
        self.server_executor.shutdown()
        self.node.destroy_node()
        self.server_node.destroy_node()
        if self.context.ok():
            rclpy.shutdown(context=self.context)


def _settle(answer: asyncio.Future[Any], ros_future: Any) -> None:
    if answer.done():  # the awaiting side gave up (timeout, disconnect)
        return
    if ros_future.cancelled():
        answer.cancel()
    elif ros_future.exception() is not None:
        answer.set_exception(ros_future.exception())
    else:
        answer.set_result(ros_future.result())
