"""Services both ways through the real bridge with roslibpy."""

from __future__ import annotations

import threading
from collections.abc import Callable

import pytest
import roslibpy

from .rosbridge_support import Inbox


def test_call_with_dict_and_with_list_args(connect: Callable[[], roslibpy.Ros]) -> None:
    service = roslibpy.Service(connect(), "/peer/set_bool", "std_srvs/SetBool")
    assert service.call(roslibpy.ServiceRequest({"data": True}), timeout=10) == {"success": True, "message": "got true"}
    client = connect()
    answers = Inbox()
    client.on("service_response", answers)  # not used by roslibpy; raw frames checked in test_errors
    assert (
        roslibpy.Service(client, "/peer/set_bool", "std_srvs/SetBool").call(
            roslibpy.ServiceRequest({"data": False}), timeout=10
        )["message"]
        == "got false"
    )


def test_missing_service_is_answered_as_a_failure(connect: Callable[[], roslibpy.Ros]) -> None:
    service = roslibpy.Service(connect(), "/no/such/service", "std_srvs/Trigger")
    with pytest.raises(roslibpy.core.ServiceException, match="Service /no/such/service does not exist"):
        service.call(roslibpy.ServiceRequest({}), timeout=10)


def test_slow_service_does_not_block_other_calls(connect: Callable[[], roslibpy.Ros]) -> None:
    client = connect()
    slow_done = Inbox()
    roslibpy.Service(client, "/peer/slow", "std_srvs/Trigger").call(
        roslibpy.ServiceRequest({}), callback=slow_done, errback=slow_done
    )
    fast = roslibpy.Service(client, "/peer/set_bool", "std_srvs/SetBool")
    for _ in range(5):
        assert fast.call(roslibpy.ServiceRequest({"data": True}), timeout=10)["success"] is True
    assert slow_done.items == [], "the slow call answered before the fast ones"
    assert slow_done.wait_for(1)[0] == {"success": True, "message": "slow answer"}


def test_client_serves_a_ros_service_called_by_another_client(connect: Callable[[], roslibpy.Ros]) -> None:
    server_client, caller_client = connect(), connect()
    served = threading.Event()

    def handler(request: dict, response: dict) -> bool:
        response["success"] = True
        response["message"] = f"served {request['data']}"
        served.set()
        return True

    provided = roslibpy.Service(server_client, "/bridge_test/provided", "std_srvs/SetBool")
    provided.advertise(handler)
    caller = roslibpy.Service(caller_client, "/bridge_test/provided", "std_srvs/SetBool")
    answer = None
    for _ in range(50):  # the advertised service appears on the ROS graph asynchronously
        try:
            answer = caller.call(roslibpy.ServiceRequest({"data": True}), timeout=10)
            break
        except roslibpy.core.ServiceException as exc:
            assert "does not exist" in str(exc) or "no server" in str(exc)
            served.wait(0.1)
    assert served.is_set()
    assert answer == {"success": True, "message": "served True"}
    provided.unadvertise()
