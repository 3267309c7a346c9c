"""``caretaker interop``: a conformance suite for rosbridge v2 servers, clients and AT servers.

It is a client of the protocol only: it speaks rosbridge v2 over its own WebSocket code and brings
whatever it needs on the ROS side through the bridge under test (client-served topics, services and
actions), so it runs against any server on any host. It imports nothing of Caretaker's bridge: a
suite that shares the server's code cannot find the server's mistakes (a test keeps it so).
"""
