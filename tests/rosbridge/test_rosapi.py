"""rosapi served by the bridge itself, through roslibpy's own rosapi helpers."""

from __future__ import annotations

from collections.abc import Callable

import roslibpy


def test_graph_queries(connect: Callable[[], roslibpy.Ros]) -> None:
    ros = connect()
    assert "/peer/echo_out" in ros.get_topics()
    assert ros.get_topic_type("/peer/echo_out") == "std_msgs/msg/String"
    services = ros.get_services()
    assert "/peer/set_bool" in services and "/rosapi/topics" in services
    assert ros.get_service_type("/peer/set_bool") == "std_srvs/srv/SetBool"
    assert "/bridge_test_peer" in ros.get_nodes()


def test_message_details_list_nested_types(connect: Callable[[], roslibpy.Ros]) -> None:
    typedefs = connect().get_message_details("geometry_msgs/PoseStamped")["typedefs"]
    by_type = {t["type"]: t for t in typedefs}
    assert typedefs[0]["type"] == "geometry_msgs/msg/PoseStamped"
    assert by_type["geometry_msgs/msg/PoseStamped"]["fieldnames"] == ["header", "pose"]
    assert by_type["geometry_msgs/msg/Point"]["fieldtypes"] == ["float64", "float64", "float64"]
    assert "std_msgs/msg/Header" in by_type and "builtin_interfaces/msg/Time" in by_type


def test_time_and_version(connect: Callable[[], roslibpy.Ros]) -> None:
    ros = connect()
    now = roslibpy.Service(ros, "/rosapi/get_time", "rosapi_msgs/srv/GetTime").call(roslibpy.ServiceRequest({}))
    assert now["time"]["sec"] > 1_600_000_000 and 0 <= now["time"]["nanosec"] < 1_000_000_000
    version = roslibpy.Service(ros, "/rosapi/get_ros_version", "rosapi_msgs/srv/GetROSVersion").call(
        roslibpy.ServiceRequest({})
    )
    assert version == {"version": 2, "distro": "jazzy"}


def test_parameters_of_a_node(connect: Callable[[], roslibpy.Ros]) -> None:
    ros = connect()
    greeting = roslibpy.Param(ros, "/bridge_test_peer:greeting")
    assert greeting.get(timeout=10) == "hello"
    greeting.set("bonjour", timeout=10)
    assert greeting.get(timeout=10) == "bonjour"
    assert "/bridge_test_peer:greeting" in ros.get_params()


def test_bridge_publishes_its_actual_port_as_a_parameter(
    connect: Callable[[], roslibpy.Ros], bridge: tuple[str, int]
) -> None:
    assert roslibpy.Param(connect(), "/rosbridge_websocket:actual_port").get(timeout=10) == bridge[1]
