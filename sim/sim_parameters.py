"""Setting the simulation node's parameters over ROS: its pace (``time_scale``) and the cabin's air.

Over ROS and not through the robot side's rosbridge: the bridge lets no client set parameters
unless its ``--set-params-glob`` allows them, and the shipped deployments allow none (an operator's
console has no business changing the simulator). What runs in the stack's ROS domain can: a
test pacing a motion, a demo injecting a fault into the cabin.
"""

from __future__ import annotations

from collections.abc import Mapping

import rclpy
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

__all__ = ["SIM_PARAMETERS", "SimParametersRefused", "parameter_request", "set_sim_parameters"]

#: The simulation node's parameter service (``caretaker sim``'s node, in the deployment's namespace).
SIM_PARAMETERS = "/caretaker_sim/set_parameters"

Value = float | str | bool


class SimParametersRefused(RuntimeError):
    """The simulation is not there, did not answer, or refused a value: the message says which."""


def parameter_request(values: Mapping[str, Value]) -> SetParameters.Request:
    """A request setting each parameter to its value, typed as given (a wrong type is the node's to refuse)."""
    parameters = []
    for name, value in values.items():
        if isinstance(value, str):
            typed = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
        elif isinstance(value, bool):
            typed = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
        elif isinstance(value, int):
            typed = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
        else:
            typed = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
        parameters.append(Parameter(name=name, value=typed))
    return SetParameters.Request(parameters=parameters)


def set_sim_parameters(values: Mapping[str, Value], *, service: str = SIM_PARAMETERS, timeout: float = 60.0) -> None:
    """Set the simulation's parameters ``values`` from now on, in this process's ROS domain.

    Raises:
        SimParametersRefused: as the class says.
    """
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("caretaker_sim_parameters", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        client = node.create_client(SetParameters, service)
        if not client.wait_for_service(timeout_sec=timeout):
            raise SimParametersRefused(f"{service} not available: is the simulation up in this ROS domain?")
        future = client.call_async(parameter_request(values))
        executor.spin_until_future_complete(future, timeout_sec=timeout)
        if not future.done():
            raise SimParametersRefused(f"{service} did not answer within {timeout:g} s")
        refused = [
            f"{name}: {r.reason}" for name, r in zip(values, future.result().results, strict=True) if not r.successful
        ]
        if refused:
            raise SimParametersRefused(f"the simulation refused {'; '.join(refused)}")
    finally:
        rclpy.try_shutdown(context=context)
