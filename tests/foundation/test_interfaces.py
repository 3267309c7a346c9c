"""affordance_template_msgs is built, imports, and carries a service call between two processes."""

from __future__ import annotations

from pathlib import Path

import pytest
import rclpy
import rclpy.executors

from support.processes import python

HERE = Path(__file__).resolve().parent


def test_status_strings_are_a_closed_set() -> None:
    from affordance_template_msgs.msg import ServerStatus

    plan = {v for k, v in vars(ServerStatus).items() if k.startswith("PLAN_") and isinstance(v, str)}
    execute = {v for k, v in vars(ServerStatus).items() if k.startswith("EXECUTE_") and isinstance(v, str)}
    assert plan == {"IDLE", "PLANNING", "PLANNED", "PLAN_FAILED"}
    assert execute == {"IDLE", "EXECUTING", "SUCCEEDED", "FAILED", "ABORTED", "HALTED"}


def test_every_service_answers_with_success_and_message() -> None:
    import affordance_template_msgs.srv as srv

    names = [n for n in dir(srv) if not n.startswith("_") and hasattr(getattr(srv, n), "Response")]
    assert len(names) >= 12
    for name in names:
        fields = getattr(srv, name).Response.get_fields_and_field_types()
        assert {"success", "message"} <= set(fields), name


@pytest.mark.ros
def test_service_round_trip_between_processes(ros_env: dict[str, str]) -> None:
    from affordance_template_msgs.srv import AddAffordanceTemplate

    server = python(str(HERE / "interface_server.py"), env=ros_env, name="interface_server")
    context = rclpy.Context()  # its own context: other suites in this process may hold the default one
    rclpy.init(context=context)
    node = rclpy.create_node("interface_client", context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    try:
        server.wait_ready(60)
        client = node.create_client(AddAffordanceTemplate, "/affordance_template_server/add_template")
        assert client.wait_for_service(timeout_sec=30), "server not discovered"
        request = AddAffordanceTemplate.Request(class_type="cdra_filter", hide_waypoints=True)
        request.pose.header.frame_id = "cabinet/slot"
        future = client.call_async(request)
        executor.add_node(node)
        executor.spin_until_future_complete(future, timeout_sec=30)
        response = future.result()
        assert response is not None, "no response"
        assert (response.success, response.id, response.instance) == (True, 7, "cdra_filter:7")
        assert response.message == "frame cabinet/slot hide=True"
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        server.stop()
