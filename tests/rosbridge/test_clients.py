"""Many clients at once, and clients that vanish: nothing stalls, nothing lingers."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import roslibpy

from .rosbridge_support import Inbox, RawClient


def test_thirty_concurrent_clients_call_and_subscribe(
    bridge: tuple[str, int], connect: Callable[[], roslibpy.Ros]
) -> None:
    clients = [connect() for _ in range(30)]
    inboxes = [Inbox() for _ in clients]
    for client, inbox in zip(clients, inboxes, strict=False):
        roslibpy.Topic(client, "/peer/latched", "std_msgs/String").subscribe(inbox)
    answers: list[dict] = []
    lock = threading.Lock()

    def call(client: roslibpy.Ros, index: int) -> None:
        answer = roslibpy.Service(client, "/peer/set_bool", "std_srvs/SetBool").call(
            roslibpy.ServiceRequest({"data": index % 2 == 0}), timeout=30
        )
        with lock:
            answers.append(answer)

    threads = [threading.Thread(target=call, args=(c, i)) for i, c in enumerate(clients)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert len(answers) == 30
    assert sum(a["success"] for a in answers) == 15
    for inbox in inboxes:
        assert inbox.wait_for(1)[0] == {"data": "latched value"}


def publishers_of(raw: RawClient, topic: str) -> list[str]:
    answer = raw.request(
        {"op": "call_service", "service": "/rosapi/publishers", "args": {"topic": topic}}, "service_response"
    )
    return answer["values"]["publishers"]


def test_clients_dropping_mid_send_leave_no_ghost_publishers(bridge: tuple[str, int]) -> None:
    observer = RawClient(*bridge)
    topic = "/bridge_test/ghost"
    try:
        for _ in range(5):
            doomed = RawClient(*bridge)
            doomed.send({"op": "advertise", "topic": topic, "type": "std_msgs/String"})
            doomed.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
            for index in range(100):
                doomed.send({"op": "publish", "topic": topic, "msg": {"data": f"{index}"}})
            doomed.connection.socket.close()  # vanish without a closing handshake
        deadline = time.monotonic() + 30
        while publishers_of(observer, topic) and time.monotonic() < deadline:
            threading.Event().wait(0.2)  # polls the bridge's graph until the publisher is gone
        assert publishers_of(observer, topic) == []
        answer = observer.request(
            {"op": "call_service", "service": "/rosapi/subscribers", "args": {"topic": topic}}, "service_response"
        )
        assert answer["values"]["subscribers"] == []
    finally:
        observer.close()
