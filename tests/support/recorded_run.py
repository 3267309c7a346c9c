"""A run recorded on the real robot side, read back and played back.

``tests/pride/fixtures/iva_recorded_run.json`` is the audit log of one autonomous run of the
shipped IVA procedure against the real stack (simulation, OMPL planner, AT server, rosbridge, the
JVM-hosted PAX plugins: ``caretaker run ... --auto``), exported as :meth:`Event.to_dict` rows. Its
values are the robot side's own: planner noise in every pose (``0.14999985294229648``,
``-3.397308328442832e-10``), instance ids, the AT server's messages.

:class:`RecordedSystems` plays that robot side back behind a real executive: each command gets
the answer it got in the recording, each telemetry read the value the recorded run read next, so
a test runs the procedure again, as it ran, without ROS.
"""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path
from typing import Any

from pride.events import Event, EventKind
from pride.systems import CancelResult, CommandResult, LinkListener, Outcome, TelemetryListener, TelemetryValue
from support.procedures import FIXTURES

__all__ = ["IVA_RUN", "RecordedSystems", "command_durations", "recorded_events"]

#: The recorded IVA run (see the module docstring).
IVA_RUN = FIXTURES / "iva_recorded_run.json"


def recorded_events(path: Path = IVA_RUN) -> list[Event]:
    """The recorded run's events, as the audit log would give them back."""
    return [
        Event(
            row["run_id"],
            row["seq"],
            EventKind(row["kind"]),
            row["actor"],
            row["instruction"],
            row["data"],
            datetime.fromisoformat(row["time"]),
        )
        for row in json.loads(path.read_text(encoding="utf-8"))
    ]


def command_durations(events: list[Event]) -> dict[str, list[float]]:
    """How long the recorded robot side took to answer each command, by command name, in the order
    sent (s, from its sent to its result): the pace a stand-in robot can take the same commands at."""
    sent: dict[str, Event] = {}
    durations: dict[str, list[float]] = {}
    for event in events:
        if event.kind is EventKind.COMMAND_SENT and event.instruction:
            sent[event.instruction] = event
        elif event.kind is EventKind.COMMAND_RESULT and event.instruction in sent:
            command = sent.pop(event.instruction)
            seconds = (event.time - command.time).total_seconds()
            durations.setdefault(str(command.data.to_json()["command"]), []).append(seconds)
    return durations


class RecordedSystems:
    """The robot side of a recorded run: the same answers to the same commands, in the same order."""

    def __init__(self, events: list[Event]) -> None:
        self._events = events
        self._answers: dict[str, list[int]] = {}  # instruction number -> indexes of its recorded results
        self._readings: dict[tuple[str, str], list[tuple[int, Any]]] = {}  # (system, item) -> (index, value)
        for index, event in enumerate(events):
            d = event.data.to_json()
            if event.kind is EventKind.COMMAND_RESULT and event.instruction:
                self._answers.setdefault(event.instruction, []).append(index)
            elif event.kind is EventKind.TELEMETRY_SEEN:
                self._readings.setdefault((d["system"], d["item"]), []).append((index, d["value"]))
            elif event.kind is EventKind.OPERATOR_INPUT and d.get("checked_against"):
                # a record checked against a telemetry item: the values the system listed then
                system, item = d["checked_against"].split(".")
                self._readings.setdefault((system, item), []).append((index, ", ".join(d["allowed"])))
        self._now = 0  # the index of the last answer given: telemetry reads what followed it
        self.sent: list[tuple[str, str, dict[str, Any]]] = []

    def system_ids(self) -> frozenset[str]:
        return frozenset({"affordance_templates", "cdra", "perception"})

    def robot(self) -> str:
        return str(self._events[0].data.to_json().get("robot", "iva"))

    def execute(
        self, sysrep_id: str, command_id: str, args: dict[str, Any], *, key: str | None = None
    ) -> CommandResult:
        """The recorded answer to the instruction the key names (``run/<number>/<attempt>``; a
        sub-procedure's number, ``1.11/2.1``, is written ``1.11:2.1`` there: automation.command_key)."""
        self.sent.append((sysrep_id, command_id, dict(args)))
        number = (key or "").split("/")[1].replace(":", "/")
        waiting = self._answers.get(number)
        if not waiting:
            return CommandResult(Outcome.FAILED, f"the recording has no answer to {number}")
        self._now = waiting.pop(0)
        data = self._events[self._now].data.to_json()
        return CommandResult(Outcome(data["outcome"]), data["message"], dict(data.get("values") or {}))

    def cancel(self, key: str) -> CancelResult:
        return CancelResult(False, "nothing runs in a recording")

    def one_way_delay(self) -> float:
        return 0.0

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        """What the recorded run read of the item after the last answer (else last before it)."""
        seen = self._readings.get((sysrep_id, item_id))
        if not seen:
            return TelemetryValue(None, None, stale=True)
        value = next((value for index, value in seen if index > self._now), seen[-1][1])
        return TelemetryValue(value, self._events[self._now].time.timestamp())

    def add_listener(self, callback: TelemetryListener) -> None:
        """Nothing changes by itself in a recording: readers poll."""

    def add_link_listener(self, callback: LinkListener) -> None:
        """A recording's link never drops."""

    def close(self) -> None:
        """Nothing to release."""
