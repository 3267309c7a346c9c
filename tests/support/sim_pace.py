"""Set the simulator's pace from a test: its ``time_scale`` parameter (or another), over ROS
(:mod:`sim.sim_parameters`, which says why not through the bridge)."""

from __future__ import annotations

from rcl_interfaces.srv import SetParameters

from sim.sim_parameters import SIM_PARAMETERS, set_sim_parameters
from sim.sim_parameters import parameter_request as parameters_request

__all__ = ["SIM_PARAMETERS", "parameter_request", "set_sim_time_scale", "time_scale_request"]


def time_scale_request(value: float | str | bool) -> SetParameters.Request:
    """A request setting ``time_scale`` to ``value``, typed as given (a wrong type, to see it refused)."""
    return parameter_request("time_scale", value)


def parameter_request(name: str, value: float | str | bool) -> SetParameters.Request:
    """A request setting the simulator's parameter ``name`` to ``value``, typed as given."""
    return parameters_request({name: value})


def set_sim_time_scale(scale: float, *, service: str = SIM_PARAMETERS, timeout: float = 60.0) -> None:
    """Pace the simulator at ``scale`` × real time from now on (0: flat out while anything moves)."""
    set_sim_parameters({"time_scale": scale}, service=service, timeout=timeout)
