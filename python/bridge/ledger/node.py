"""The habitat's command ledger node: every command key executes at most once, and its outcome is kept.

Services (docs/interfaces.md, "Command ledger"):

- ``/command_ledger/execute`` (``caretaker_ledger_msgs/srv/ExecuteOnce``): call the named ROS
  service for a command key, unless the key is known: then answer its recorded outcome, or
  wait for the call in progress and answer its outcome (a re-send *joins* the call).
- ``/command_ledger/outcome`` (``caretaker_ledger_msgs/srv/CommandOutcome``): what became of
  a key, without executing anything.

A key is recorded as in progress (committed) before its service is called, and its outcome is
committed before the answer goes out, so neither a lost answer nor a restart can make a key
run twice: a restarted ledger answers UNKNOWN for the calls it was running when it stopped.

A request with an ``issued`` field (builtin_interfaces/Time: the AT server's execute and plan)
is stamped with the time its command reached the ledger, so the robot side orders it against the
halts that reached it meanwhile (:mod:`ros_process.command_order`): a halt that overtook a command
still waiting here keeps it from moving the robot.

Threading: a MultiThreadedExecutor; each execute request blocks one of its threads until the
called service answers, while the answers themselves are taken on other threads.
``_calls_lock`` makes "is this key known or running, else claim it" one step.
"""

from __future__ import annotations

import json
import logging
import re
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from caretaker_ledger_msgs.srv import CommandOutcome, ExecuteOnce  # type: ignore[import-untyped]
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from ros_process.command_order import arrived_now
from ros_process.delay_hooks import pause

from .service_calls import SERVICE_QOS, CallOutcome, Refusal, ServiceCaller, answer_outcome, valid_timeout
from .store import LedgerStore, Record, State

__all__ = ["EXECUTE_SERVICE", "OUTCOME_SERVICE", "LedgerNode"]

log = logging.getLogger(__name__)

EXECUTE_SERVICE = "/command_ledger/execute"
OUTCOME_SERVICE = "/command_ledger/outcome"
MAX_TIMEOUT_S = 24 * 3600.0
"""The longest wait a request may ask for (a day): anything longer is a mistake."""
JOIN_MARGIN_S = 10.0
"""How much longer than the running call's own limit a joining re-send waits for it."""
PRUNE_PERIOD_S = 3600.0
_KEY = re.compile(r"^[^/\s]+/[^/\s]+/[0-9]+$")


@dataclass
class RunningCall:
    """A call in progress; re-sends of its key wait on ``done`` and answer its outcome."""

    service: str
    request_json: str
    deadline: float
    done: threading.Event = field(default_factory=threading.Event)
    outcome: CallOutcome | None = None


class LedgerNode(Node):
    """The ``command_ledger`` node over one :class:`LedgerStore`."""

    def __init__(self, store: LedgerStore, *, default_timeout: float) -> None:
        super().__init__("command_ledger")
        self.store = store
        self.default_timeout = default_timeout
        self.caller = ServiceCaller(self)
        self._running: dict[str, RunningCall] = {}
        self._calls_lock = threading.Lock()
        group = ReentrantCallbackGroup()
        self.execute_service = self.create_service(
            ExecuteOnce, EXECUTE_SERVICE, self.execute_callback, qos_profile=SERVICE_QOS, callback_group=group
        )
        self.outcome_service = self.create_service(
            CommandOutcome, OUTCOME_SERVICE, self.outcome_callback, qos_profile=SERVICE_QOS, callback_group=group
        )
        self.prune_timer = self.create_timer(PRUNE_PERIOD_S, self.prune_timer_callback, callback_group=group)

    # --- execute ------------------------------------------------------------------------------
    def execute_callback(self, request: Any, response: Any) -> Any:
        key = request.command_key
        arrived = arrived_now()  # when the command reached the robot side: the order against halts
        response.epoch = self.store.epoch
        try:
            if not _KEY.match(key):
                raise Refusal(f"command_key must be '<run_id>/<instruction>/<attempt>', got {key!r}")
            timeout = valid_timeout(request.timeout, self.default_timeout, MAX_TIMEOUT_S)
        except Refusal as exc:
            return _answer(response, CallOutcome(State.REFUSED, "", str(exc)))
        mine: RunningCall | None = None
        with self._calls_lock:
            running = self._running.get(key)
            record = self.store.get(key) if running is None else None
            if running is None and record is None:
                if request.epoch and request.epoch != self.store.epoch:
                    log.warning(
                        "%s: unknown key re-sent under epoch %s (now %s): UNKNOWN, not executed",
                        key,
                        request.epoch,
                        self.store.epoch,
                    )
                    return _answer(
                        response,
                        CallOutcome(
                            State.UNKNOWN,
                            "",
                            f"this ledger's memory is newer than the client's (epoch {request.epoch},"
                            f" now {self.store.epoch}) and has no record of {key}:"
                            " whether it executed cannot be learnt;"
                            " not executed now",
                        ),
                    )
                self.store.begin(key, request.service, request.type, request.request_json)
                mine = self._running[key] = RunningCall(
                    request.service, request.request_json, time.monotonic() + timeout + JOIN_MARGIN_S
                )
        if running is not None:
            return _answer(response, self._join(key, running, request))
        if record is not None:
            return _answer(response, self._recorded(key, record, request))
        assert mine is not None  # claimed above: neither running nor recorded
        return _answer(response, self._perform(key, mine, request, timeout, arrived))

    def _perform(self, key: str, mine: RunningCall, request: Any, timeout: float, arrived: float) -> CallOutcome:
        pause("ledger.forward")
        log.info("%s: calling %s", key, request.service)
        try:
            outcome = self.caller.call(request.service, request.type, request.request_json, timeout, issued=arrived)
        except Exception as exc:  # the key is claimed: it must end with an answer, whatever failed
            log.exception("%s: the ledger failed during the call", key)
            outcome = CallOutcome(
                State.UNKNOWN, "", f"the ledger failed during the call ({exc!r}); it may have executed"
            )
        self.store.finish(key, outcome.state, outcome.response_json, outcome.message)
        if outcome.late_answer is not None:
            outcome.late_answer.add_done_callback(lambda future: self._late_answer(key, request.service, future))
        log.info("%s: %s %s", key, outcome.state.value, outcome.message)
        with self._calls_lock:
            mine.outcome = outcome
            del self._running[key]
        mine.done.set()
        return outcome

    def _late_answer(self, key: str, service: str, future: Any) -> None:
        outcome = answer_outcome(service, future)
        message = f"answered after the ledger stopped waiting: {outcome.message}".rstrip(": ")
        if self.store.finish(key, outcome.state, outcome.response_json, message, was=State.UNKNOWN):
            log.info("%s: late answer recorded: %s", key, outcome.state.value)

    def _join(self, key: str, running: RunningCall, request: Any) -> CallOutcome:
        if not _same_command(running.service, running.request_json, request):
            return _reused(key, running.service)
        log.info("%s: re-sent while in progress: joining the call", key)
        if not running.done.wait(max(0.0, running.deadline - time.monotonic())) or running.outcome is None:
            return CallOutcome(State.UNKNOWN, "", f"{key} is still in progress past its time limit")
        return running.outcome

    def _recorded(self, key: str, record: Record, request: Any) -> CallOutcome:
        if not _same_command(record.service, record.request_json, request):
            return _reused(key, record.service)
        log.info("%s: re-sent: answered from the record (%s)", key, record.state.value)
        return CallOutcome(record.state, record.response_json, f"recorded outcome: {record.message}".rstrip(": "))

    # --- outcome ------------------------------------------------------------------------------
    def outcome_callback(self, request: Any, response: Any) -> Any:
        key = request.command_key
        response.epoch = self.store.epoch
        with self._calls_lock:
            running = self._running.get(key)
        record = self.store.get(key) if key else None
        if running is not None or (record is not None and record.state is State.IN_PROGRESS):
            response.state = CommandOutcome.Response.IN_PROGRESS
            response.service = running.service if running is not None else record.service if record else ""
            response.message = "the call is in progress"
        elif record is None:
            response.state = CommandOutcome.Response.NOT_FOUND
            response.message = f"no record of {key!r} in epoch {self.store.epoch}" if key else "epoch only"
        else:
            response.state = record.state.value
            response.service = record.service
            response.response_json = record.response_json
            response.message = record.message
        return response

    def prune_timer_callback(self) -> None:
        pruned = self.store.prune()
        if pruned:
            log.info("pruned %d records past retention; new epoch %s", pruned, self.store.epoch)


def _answer(response: Any, outcome: CallOutcome) -> Any:
    response.state = outcome.state.value
    response.response_json = outcome.response_json
    response.message = outcome.message
    return response


def _same_command(service: str, request_json: str, request: Any) -> bool:
    """Whether a re-send names the same call as the key's first send (JSON compared as data)."""
    if service != request.service:
        return False
    try:
        return bool(json.loads(request_json or "{}") == json.loads(request.request_json or "{}"))
    except ValueError:
        return bool(request_json == request.request_json)


def _reused(key: str, service: str) -> CallOutcome:
    return CallOutcome(
        State.REFUSED,
        "",
        f"command key {key} already names another call (of {service}):"
        " a key is one command; use a new attempt number for a new command",
    )
