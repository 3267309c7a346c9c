"""The ``clients`` profile: scripted scenarios that check a rosbridge v2 *client*, and drivers.

``caretaker interop --serve PORT --profile clients`` (:mod:`interop.scripted_server`) plays a
rosbridge server whose answers are scripted per case (:mod:`interop.clients.scenarios`). A small
driver program per client library makes the client do what each case needs and reports what the
client handed to it through the client itself (a call of ``/interop/report`` on a second
connection), so the server judges from the frames it saw and from what the program received.
The drivers here are the ones for third-party clients (roslibpy, roslibjs) and the Java client;
they show integrators how to write one for theirs.
"""
