"""Set the simulator's pace from a test: its ``time_scale`` parameter (or another), over ROS.

Why over ROS and not the stack's rosbridge: the bridge lets no client set parameters unless its
``--set-params-glob`` allows them, and the shipped deployments allow none (an operator's console
has no business changing the simulator's clock). A test in the stack's ROS domain can.
"""

from __future__ import annotations

import rclpy
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

__all__ = ["SIM_PARAMETERS", "parameter_request", "set_sim_time_scale", "time_scale_request"]

#: The simulator node's parameter service (``caretaker sim``'s node, namespace of the deployment).
SIM_PARAMETERS = "/caretaker_sim/set_parameters"


def time_scale_request(value: float | str | bool) -> SetParameters.Request:
    """A request setting ``time_scale`` to ``value``, typed as given (a wrong type, to see it refused)."""
    return parameter_request("time_scale", value)


def parameter_request(name: str, value: float | str | bool) -> SetParameters.Request:
    """A request setting the simulator's parameter ``name`` to ``value``, typed as given."""
    if isinstance(value, str):
        typed = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    elif isinstance(value, bool):
        typed = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    elif isinstance(value, int):
        typed = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    else:
        typed = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    return SetParameters.Request(parameters=[Parameter(name=name, value=typed)])


def set_sim_time_scale(scale: float, *, service: str = SIM_PARAMETERS, timeout: float = 60.0) -> None:
    """Pace the simulator at ``scale`` × real time from now on (0: flat out while anything moves)."""
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("test_sim_pace", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        client = node.create_client(SetParameters, service)
        if not client.wait_for_service(timeout_sec=timeout):
            raise AssertionError(f"{service} not available: is the simulator up in this ROS domain?")
        future = client.call_async(time_scale_request(scale))
        executor.spin_until_future_complete(future, timeout_sec=timeout)
        if not future.done():
            raise AssertionError(f"{service} did not answer within {timeout} s")
        result = future.result().results[0]
        if not result.successful:
            raise AssertionError(f"time_scale {scale} refused: {result.reason}")
    finally:
        rclpy.try_shutdown(context=context)
