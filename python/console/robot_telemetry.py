"""A robot's telemetry as the ground reads it outside any run: through the PAX host of its binding.

A proposal shows an operator the telemetry an agent cited with its values now, and an agent reads
a robot's telemetry against its limits, whether or not a run is on the robot. Both read it here,
the way a run would: the binding that reaches the robot (from the consoles' bindings folder), its
gateway opened at the first read and kept (a JVM host and a rosbridge session are seconds to open
on a loaded host), every item of every SysRep it serves.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from console.catalog import Catalog, rosbridge_for
from pride.gateways import open_gateway
from pride.run_setup import load_sysreps
from pride.systems import SystemGateway
from procedure_language.binding import BindingError, read_binding
from procedure_language.sysrep import Telemetry
from records.refusals import Refused

__all__ = ["RobotTelemetry", "TelemetryFacts", "TelemetryRefused"]


class TelemetryRefused(Refused):
    """A robot or SysRep that cannot be read: ``rule`` names what is missing, the message says what."""


@dataclass(frozen=True)
class TelemetryFacts:
    """One telemetry item as read now: ``value`` None until first heard, ``age`` in s."""

    system: str
    item: Telemetry
    value: Any
    age: float | None
    stale: bool

    @property
    def state(self) -> str:
        """green, yellow or red against the item's limits; ``no limits``; ``no value`` when unknown."""
        if self.value is None or self.stale:
            return "no value" if self.value is None else "stale"
        return self.item.limits.state(self.value) if self.item.limits is not None else "no limits"


class RobotTelemetry:
    """The robots of ``catalog``'s bindings and their telemetry, each robot's gateway opened once."""

    def __init__(
        self,
        catalog: Catalog,
        rosbridge_urls: Mapping[str, str] | None = None,
        gateways: Callable[..., SystemGateway] = open_gateway,
    ) -> None:
        self.catalog = catalog
        self.rosbridge_urls = dict(rosbridge_urls or {})  # as the consoles' --rosbridge says
        self._open_gateway = gateways
        self._lock = threading.Lock()  # one opening per robot, whoever asks at once
        self._watched: dict[str, tuple[SystemGateway, list[tuple[str, Telemetry]]]] = {}

    def robots(self) -> dict[str, str]:
        """Robot name → the binding file that reaches it."""
        robots: dict[str, str] = {}
        for name in self.catalog.binding_files():
            try:
                robots.setdefault(read_binding(self.catalog.bindings / name).robot, name)
            except BindingError:
                continue  # a console cannot use it either
        return robots

    def binding_of(self, robot: str) -> str:
        """The binding file that reaches ``robot``; TelemetryRefused (known_robot) when there is none."""
        robots = self.robots()
        if robot not in robots:
            raise TelemetryRefused(
                "known_robot", f"no robot {robot!r} here (robots: {', '.join(sorted(robots)) or 'none'})"
            )
        return robots[robot]

    def read(self, robot: str) -> list[TelemetryFacts]:
        """Every item ``robot``'s binding serves: its value now, how old, whether stale."""
        with self._lock:
            gateway, items = self._watched.get(robot) or self._watch(robot)
        now = time.time()
        facts = []
        for sysrep_id, item in items:
            reading = gateway.telemetry(sysrep_id, item.id)
            age = None if reading.timestamp is None else max(0.0, now - reading.timestamp)
            facts.append(TelemetryFacts(sysrep_id, item, reading.value, age, reading.stale))
        return facts

    def close(self) -> None:
        with self._lock:
            for gateway, _ in self._watched.values():
                gateway.close()
            self._watched.clear()

    def _watch(self, robot: str) -> tuple[SystemGateway, list[tuple[str, Telemetry]]]:
        binding = self.binding_of(robot)
        sysreps = load_sysreps(self.catalog.sysreps)
        items = []
        for system in read_binding(self.catalog.binding_path(binding)).systems:
            sysrep = sysreps.get(system.sysrep)
            if sysrep is None:  # the binding does not lint: a console refuses it too
                raise TelemetryRefused("known_sysrep", f"{binding} names SysRep {system.sysrep!r}, which is not loaded")
            items += [(sysrep.id, item) for item in sysrep.telemetry]
        path, url = str(self.catalog.binding_path(binding)), rosbridge_for(self.rosbridge_urls, binding)
        self._watched[robot] = (self._open_gateway(path, rosbridge_url=url), items)
        return self._watched[robot]
