"""The cabin's CO2 on the simulation node: ``cdra/co2_partial_pressure`` (std_msgs/Float64, mmHg).

Latched, so a part that starts late reads the cabin at once, and published once per second of
sim time: the value changes continuously (sim/cabin_air.py), so publishing it on change would
send it at the stepper's rate. Looked at a few times a wall second, so that at ``--time-scale 0``
a fast motion does not send dozens of samples a wall second either. Successive samples are at
least a sim second apart, so each says how the cabin went over that second.

The cabin's knobs (sim/cabin_knobs.py) are parameters of the node, set at run time as at launch:
a value out of range is refused with the reason, and the cabin stays as it was.
"""

from __future__ import annotations

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64

from sim.cabin_knobs import BY_NAME, KNOBS, set_knobs
from sim.simulation import Simulation

__all__ = ["CabinAirInterface"]

#: s of sim time between samples
PUBLISH_PERIOD = 1.0
#: s of wall time between looks at the sim clock
LOOK_PERIOD = 0.25


class CabinAirInterface:
    """Publishes ``sim``'s cabin CO2 (which has a cabinet, hence a cabin) from ``node``."""

    def __init__(self, node: Node, sim: Simulation, *, latched: QoSProfile, group: CallbackGroup) -> None:
        if sim.cabin_air is None:
            raise ValueError("the scene has no CDRA cabinet: its cabin has no CO2 removal to publish")
        self._sim = sim
        self._published_at: float | None = None
        self.pub = node.create_publisher(Float64, "cdra/co2_partial_pressure", latched)
        self.timer = node.create_timer(LOOK_PERIOD, self.publish_when_due, callback_group=group)
        for knob in KNOBS:  # as the simulation started; dynamic typing: 60 (an integer) is as good as 60.0
            descriptor = ParameterDescriptor(description=knob.help, dynamic_typing=True)
            node.declare_parameter(knob.parameter, getattr(sim.cabin_air, knob.attribute), descriptor)
        node.add_on_set_parameters_callback(self._on_set_knobs)

    def _on_set_knobs(self, parameters: list[Parameter]) -> SetParametersResult:
        """Set the knobs among ``parameters`` on the cabin, all of them or (one refused) none."""
        values = {p.name: p.value for p in parameters if p.name in BY_NAME}
        for name, value in values.items():
            refused = BY_NAME[name].refusal(value)
            if refused is not None:
                return SetParametersResult(successful=False, reason=refused)
        with self._sim.world_lock:
            assert self._sim.cabin_air is not None
            set_knobs(self._sim.cabin_air, values)
        return SetParametersResult(successful=True)

    def publish_when_due(self) -> None:
        with self._sim.world_lock:
            air = self._sim.cabin_air
            assert air is not None
            due = self._published_at is None or air.time - self._published_at >= PUBLISH_PERIOD
            if due:
                self._published_at, ppco2 = air.time, air.ppco2
        if due:
            self.pub.publish(Float64(data=ppco2))
