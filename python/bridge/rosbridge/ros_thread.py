"""ROS 2 side of the bridge: rclpy on dedicated threads, topic messages taken on the event loop.

Topic subscriptions (the hot path) belong to :attr:`RosThread.topic_node`, which no executor
spins (an executor would install its own callback on them).  rcl lets a subscription report
new messages through a plain C callback, called on the middleware's listener thread: the hook
rclpy's ``EventsExecutor`` uses, which the Python handle does not expose, so
:class:`LoopSubscription` sets it through ``ctypes``.  The callback is libc's
``eventfd_write``, which needs no GIL: the listener thread bumps an eventfd that the event
loop watches, and the loop takes the messages itself.  A message thus reaches its WebSocket
clients with one thread wake-up (the loop's), as in the Rust peer; handing it over from an
executor thread cost a second wake-up, a GIL hand-off and a ``call_soon_threadsafe``.

Threads and their jobs:

* ``ros-events``: an ``EventsExecutor`` turned by ``spin_once`` in a loop (``spin()`` does not
  work in the Jazzy 7.1.6 wheels), for :attr:`RosThread.node`: service *clients* and the
  node's parameter services.  It was about 5x faster than the default executor.
* ``ros-servers``: a ``SingleThreadedExecutor`` for :attr:`RosThread.server_node`, which holds
  entities whose callbacks must wait for a WebSocket client (services and actions that a
  client serves, action clients).  They need coroutine callbacks, which the EventsExecutor
  does not run.
* the asyncio thread (uvloop) owns every WebSocket and all per-connection state, and takes
  topic messages.

Entity creation, publishing, taking and ``call_async`` are thread-safe in rclpy, so the
asyncio side calls them directly.  Everything else flowing from ROS back to asyncio (service
responses, requests to client-served services, action events) goes through
:meth:`RosThread.deliver`, which batches callbacks into the event loop with at most one
pending wake-up, so a burst costs one ``call_soon_threadsafe``.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import logging
import os
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rclpy.type_description_service import START_TYPE_DESCRIPTION_SERVICE_PARAM

from .protocol import ServiceUnanswered

log = logging.getLogger(__name__)

NODE_NAME = "rosbridge_websocket"
TAKE_BATCH = 64
"""Messages one subscription takes per event-loop turn; more wait for the next turn, so a
busy topic never keeps the loop from reading sockets."""

_set_on_new_message = ctypes.CDLL("librcl.so").rcl_subscription_set_on_new_message_callback  # loaded by rclpy
_set_on_new_message.argtypes = (ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)
_set_on_new_message.restype = ctypes.c_int
_EVENTFD_WRITE = ctypes.cast(ctypes.CDLL(None).eventfd_write, ctypes.c_void_p)
"""libc's ``eventfd_write(int fd, uint64_t n)`` serves as rcl's ``void (*)(const void *user_data,
size_t n)`` with the eventfd's number as ``user_data``: both take their two arguments in the
same registers on the x86-64 and AArch64 calling conventions."""


class RosThread:
    """rclpy context, the bridge's nodes, and the threads that spin them."""

    def __init__(self, loop: asyncio.AbstractEventLoop, node_name: str = NODE_NAME) -> None:
        self.loop = loop
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(node_name, context=self.context)
        self.server_node = rclpy.create_node(f"{node_name}_servers", context=self.context)
        # No executor serves topic_node, so it must offer no services (parameters, type
        # descriptions) that callers would wait on in vain.
        self.topic_node = rclpy.create_node(
            f"{node_name}_topics",
            context=self.context,
            start_parameter_services=False,
            parameter_overrides=[Parameter(START_TYPE_DESCRIPTION_SERVICE_PARAM, value=False)],
        )
        self._loop_subscriptions: set[LoopSubscription] = set()
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
            with contextlib.suppress(RuntimeError):  # a loop closed at shutdown: nobody is left to tell
                self.loop.call_soon_threadsafe(self._drain)

    def wrap(self, ros_future: Any) -> asyncio.Future[Any]:
        """An asyncio future (of the event loop) settled when the rclpy ``ros_future`` is."""
        answer: asyncio.Future[Any] = self.loop.create_future()
        ros_future.add_done_callback(lambda done: self.deliver(_settle, answer, done))
        return answer

    def on_server_thread(self, function: Callable[..., Any], *args: Any, **kwargs: Any) -> asyncio.Future[Any]:
        """``function(*args, **kwargs)`` run on the ``ros-servers`` thread; an event-loop future of
        its result.

        For requests of :attr:`server_node`'s action clients: rclpy 7.1's ``ActionClient`` sends
        a goal, result or cancel request and only then records it, so the thread executing the
        client could take the answer in between and drop it (the request would never be
        answered).  Sent from that very thread, a request is on record before it can look.
        """
        return self.wrap(self.server_executor.create_task(function, *args, **kwargs))

    async def ask(self, request: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Send ``request(*args, **kwargs)`` (which returns an rclpy future, e.g. an action
        client's ``send_goal_async``) from the ``ros-servers`` thread and await its answer."""
        return await self.wrap(await self.on_server_thread(request, *args, **kwargs))

    def take_on_loop(self, subscription: Any, on_message: Callable[[Any], None]) -> LoopSubscription:
        """Call ``on_message(message)`` on the event loop for each message of ``subscription``
        (created on :attr:`topic_node`); close the result before destroying the subscription."""
        watch = LoopSubscription(self.loop, subscription, on_message, self._loop_subscriptions.discard)
        self._loop_subscriptions.add(watch)
        return watch

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
            except ServiceUnanswered:
                pass  # left without a ROS response on purpose, and logged where it ended (services.py)
            except Exception:
                if self._running:
                    log.exception("a ROS callback failed")

    def shutdown(self) -> None:
        """Stop the threads and tear down nodes and context (idempotent)."""
        if not self._running:
            return
        self._running = False
        for watch in list(self._loop_subscriptions):
            watch.close()
        self.server_executor.wake()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._events.shutdown()
        self.server_executor.shutdown()
        self.node.destroy_node()
        self.server_node.destroy_node()
        self.topic_node.destroy_node()
        if self.context.ok():
            rclpy.shutdown(context=self.context)


class LoopSubscription:
    """Takes the messages of one subscription on the event loop, woken through an eventfd.

    rcl reports how many messages arrived (the eventfd adds the counts up), so the loop takes
    exactly that many: taking until the middleware says "none left" costs one more take per
    wake-up, as much as a real one.
    """

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        subscription: Any,
        on_message: Callable[[Any], None],
        on_close: Callable[[LoopSubscription], None],
    ) -> None:
        self._loop = loop
        self._subscription = subscription
        self._on_message = on_message
        self._on_close = on_close
        self._pending = 0  # messages reported and not taken yet
        self._scheduled = False  # a take turn is scheduled because a batch left messages
        self._fd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
        loop.add_reader(self._fd, self._ready)
        if _set_on_new_message(subscription.handle.pointer, _EVENTFD_WRITE, self._fd) != 0:
            self.close()
            raise RuntimeError(f"cannot watch the subscription of {subscription.topic_name}")

    def _ready(self) -> None:
        try:
            self._pending += os.eventfd_read(self._fd)  # reads and resets the count
        except BlockingIOError:
            return
        self._take()

    def _take(self) -> None:
        self._scheduled = False
        handle, msg_type = self._subscription.handle, self._subscription.msg_type
        for _ in range(min(self._pending, TAKE_BATCH)):
            taken = handle.take_message(msg_type, False)
            if taken is None:  # reported messages were dropped (history depth): none are left
                self._pending = 0
                return
            self._pending -= 1
            try:
                self._on_message(taken[0])
            except Exception:
                log.exception("handling a message of %s failed", self._subscription.topic_name)
        if self._pending and not self._scheduled:
            self._scheduled = True
            self._loop.call_soon(self._take)

    def close(self) -> None:
        """Stop taking (idempotent); the middleware calls nothing of it afterwards."""
        if self._fd < 0:
            return
        _set_on_new_message(self._subscription.handle.pointer, None, None)
        self._pending = 0  # a scheduled take turn then takes nothing
        self._loop.remove_reader(self._fd)
        os.close(self._fd)
        self._fd = -1
        self._on_close(self)


def _settle(answer: asyncio.Future[Any], ros_future: Any) -> None:
    if answer.done():  # the awaiting side gave up (timeout, disconnect)
        return
    if ros_future.cancelled():
        answer.cancel()
    elif ros_future.exception() is not None:
        answer.set_exception(ros_future.exception())
    else:
        answer.set_result(ros_future.result())
