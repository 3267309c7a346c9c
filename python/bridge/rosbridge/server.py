"""``caretaker bridge``: the rosbridge v2 WebSocket server on rclpy.

One asyncio thread owns every WebSocket; ROS runs on its own threads (:mod:`.ros_thread`).
Prints ``READY bridge ws://HOST:PORT`` (the actual port, also with ``--port 0``) once it
accepts connections.  Loopback only unless ``--address`` says otherwise.  Options for TLS,
allow-lists, the incoming size limit and authentication are described in docs/rosbridge.md
and :mod:`.security`.
"""

from __future__ import annotations

import argparse
import asyncio
import enum
import functools
import json
import logging
import os
import signal
import ssl
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import uvloop
from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed
from websockets.frames import DATA_OPCODES, Frame, apply_mask
from websockets.protocol import State

from .actions import Actions
from .operations import Bridge, Policy
from .protocol import CLOSE_POLICY_VIOLATION, Refused
from .ros_thread import RosThread
from .security import AllowList, authenticate
from .services import Services
from .session import FIN_TEXT, Session, SessionState
from .topics import Topics

log = logging.getLogger("bridge.rosbridge")

AUTH_SECRET_ENV = "CARETAKER_BRIDGE_SECRET"
DDS_PROFILE = Path(__file__).with_name("fastdds_profile.xml")
DDS_PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="caretaker bridge", description="rosbridge v2 server on rclpy")
    parser.add_argument("--address", default="127.0.0.1", help="interface to bind (default: loopback only)")
    parser.add_argument("--port", type=int, default=9090, help="TCP port; 0 picks a free one (default 9090)")
    parser.add_argument("--certfile", help="TLS certificate (PEM); with --keyfile serves wss://")
    parser.add_argument("--keyfile", help="TLS private key (PEM)")
    parser.add_argument("--topics-glob", action="append", default=[], metavar="GLOB",
                        help="allow only matching topics (repeatable; default: all)")
    parser.add_argument("--services-glob", action="append", default=[], metavar="GLOB",
                        help="allow only matching services (repeatable; /rosapi/* stays allowed)")
    parser.add_argument("--actions-glob", action="append", default=[], metavar="GLOB",
                        help="allow only matching actions (repeatable; default: all)")
    parser.add_argument("--max-message-size", type=int, default=10_000_000,
                        help="largest incoming frame in bytes; larger closes with 1009 (default 10 MB)")
    parser.add_argument("--service-timeout", type=float, default=10.0,
                        help="default call_service timeout in seconds when a call gives none (default 10)")
    parser.add_argument("--auth-secret-file",
                        help=f"file holding the shared secret clients must authenticate with "
                             f"(or set {AUTH_SECRET_ENV}); see docs/rosbridge.md")
    parser.add_argument("--log-level", default="INFO")
    args = parser.parse_args(argv)
    if bool(args.certfile) != bool(args.keyfile):
        parser.error("--certfile and --keyfile go together")
    return args


class Framing(enum.Enum):
    """Who splits a connection's incoming bytes into WebSocket frames."""

    HANDSHAKE = "handshake"
    """websockets reads the HTTP upgrade request; the bridge watches for bytes pipelined after it."""
    BRIDGE = "bridge"
    """:meth:`BridgeConnection._receive_frames` splits frames; websockets gets all but plain text frames."""
    WEBSOCKETS = "websockets"
    """websockets parses everything (frames came before the handshake ended, or one it must refuse)."""


class BridgeConnection(ServerConnection):
    """A WebSocket connection that hands complete text messages to the bridge as they arrive.

    websockets parses frames in Python generators (about 8 % of the bridge's busy main thread
    in a py-spy profile of the echo benchmark) and hands each message to the handler task
    through a queue and a task wake-up (about 30 µs of CPU per message here).  Once the
    handshake is done, this connection splits the incoming bytes into frames itself.  A masked, unfragmented
    text frame within the size limit goes straight to :attr:`on_text` (once a session is open
    and nothing waits in websockets' queue, so messages keep their order).  Every other frame
    (control, binary, fragmented, invalid) is handed whole to websockets, whose parser thus
    always sits at a frame boundary and answers it as it would have: pongs, close codes 1002,
    1007 and 1009.

    This leans on websockets 17.4's connection internals (``data_received``, ``process_event``,
    ``protocol.state``, ``protocol.max_message_size``), pinned in requirements.txt;
    tests/rosbridge/test_framing.py and test_errors.py show whether an upgrade keeps them.
    """

    on_text: Callable[[str], None] | None = None
    _queued = 0  # messages put in the queue and not yet read by the handler (see message_read)
    _fragmented = False  # the queue holds the first frames of a fragmented message
    _framing = Framing.HANDSHAKE
    _request_ended = False  # the blank line ending the HTTP request has been received
    _tail = b""  # the last bytes of the request so far, to find its end across reads
    _buffer: bytearray

    def data_received(self, data: bytes) -> None:
        if self._framing is Framing.BRIDGE:
            self._receive_frames(data)
            return
        if self._framing is Framing.HANDSHAKE:
            if self.protocol.state is State.OPEN:
                self._framing = Framing.BRIDGE
                self._buffer = bytearray()
                self._receive_frames(data)
                return
            self._watch_request(data)
        super().data_received(data)

    def _watch_request(self, data: bytes) -> None:
        """Leave framing to websockets if bytes follow the HTTP request before the handshake
        ends: its parser may already hold part of a frame.  Clients wait for the 101 answer."""
        if self._request_ended:
            self._framing = Framing.WEBSOCKETS
            return
        joined = self._tail + data
        end = joined.find(b"\r\n\r\n")
        if end < 0:
            self._tail = joined[-3:]
            return
        self._request_ended = True
        if end + 4 < len(joined):
            self._framing = Framing.WEBSOCKETS

    def _receive_frames(self, data: bytes) -> None:
        buffer = self._buffer
        buffer += data
        size = len(buffer)
        offset = 0
        protocol = self.protocol
        while size - offset >= 2:
            second = buffer[offset + 1]
            length = second & 0x7F
            start = offset + 2
            if length == 126:
                if size - start < 2:
                    break
                length = int.from_bytes(buffer[start:start + 2], "big")
                start += 2
            elif length == 127:
                if size - start < 8:
                    break
                length = int.from_bytes(buffer[start:start + 8], "big")
                start += 8
            if (protocol.state is not State.OPEN or not second & 0x80
                    or (protocol.max_message_size is not None and length > protocol.max_message_size)):
                # closing, an unmasked frame, or one too big: websockets takes over and refuses it
                self._framing = Framing.WEBSOCKETS
                rest = bytes(buffer[offset:])
                buffer.clear()
                super().data_received(rest)
                return
            end = start + 4 + length
            if end > size:
                break
            text = None
            if buffer[offset] == FIN_TEXT and self.on_text is not None and not self._queued and not self._fragmented:
                try:
                    text = apply_mask(buffer[start + 4:end], buffer[start:start + 4]).decode()
                except UnicodeDecodeError:
                    pass  # websockets closes the connection with 1007
            if text is None:
                super().data_received(bytes(buffer[offset:end]))
            else:
                self.on_text(text)
            offset = end
        del buffer[:offset]

    def process_event(self, event: Any) -> None:
        if isinstance(event, Frame) and event.opcode in DATA_OPCODES:
            self._fragmented = not event.fin
            if event.fin:
                self._queued += 1
        super().process_event(event)

    def message_read(self) -> None:
        """The handler took one message from the queue."""
        self._queued -= 1


class RosbridgeServer:
    """The WebSocket side: accepts connections and runs one :class:`Session` per client."""

    def __init__(self, bridge: Bridge, auth_secret: str | None) -> None:
        self.bridge = bridge
        self.auth_secret = auth_secret
        self.sessions: set[Session] = set()

    async def connection(self, websocket: BridgeConnection) -> None:
        session = Session(websocket, authenticated=self.auth_secret is None)
        self.sessions.add(session)
        log.info("client %d connected from %s (%d connected)", session.number, session.peer, len(self.sessions))
        handle = functools.partial(self.bridge.handle_frame, session)
        try:
            if session.state is SessionState.OPEN:
                websocket.on_text = handle
            async for frame in websocket:
                websocket.message_read()
                if session.state is SessionState.AUTHENTICATING:
                    if not await self._authenticate(session, frame):
                        break
                    websocket.on_text = handle
                    continue
                handle(frame)
        except ConnectionClosed:
            pass
        finally:
            websocket.on_text = None
            session.mark_closed()
            self.sessions.discard(session)
            self.bridge.drop_session(session)
            log.info("client %d disconnected (%d connected)", session.number, len(self.sessions))

    async def _authenticate(self, session: Session, frame: str | bytes) -> bool:
        try:
            message: Any = json.loads(frame) if isinstance(frame, str) else None
        except json.JSONDecodeError:
            message = None
        try:
            authenticate(message, self.auth_secret or "")
        except Refused as exc:
            log.warning("client %d refused: %s", session.number, exc)
            await session.websocket.close(CLOSE_POLICY_VIOLATION, str(exc)[:120])
            return False
        session.state = SessionState.OPEN
        return True


async def run(args: argparse.Namespace) -> int:
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(signum, stop.set)
    secret = _read_secret(args.auth_secret_file)
    tls = None
    if args.certfile:
        tls = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        tls.load_cert_chain(args.certfile, args.keyfile)
    ros = RosThread(loop)
    try:
        policy = Policy(AllowList("topic", tuple(args.topics_glob)), AllowList("service", tuple(args.services_glob)),
                        AllowList("action", tuple(args.actions_glob)), args.max_message_size)
        topics = Topics(ros)
        services = Services(ros, args.service_timeout)
        bridge = Bridge(topics, services, Actions(ros, policy.actions), policy)
        server = RosbridgeServer(bridge, secret)
        async with serve(server.connection, args.address, args.port, ssl=tls, max_size=args.max_message_size,
                         compression=None, ping_interval=20, ping_timeout=30,
                         create_connection=BridgeConnection) as ws_server:
            port = ws_server.sockets[0].getsockname()[1]
            # rosbridge's own launch tests read the bound port from this parameter
            ros.node.declare_parameter("actual_port", port)
            scheme = "wss" if tls else "ws"
            print(f"READY bridge {scheme}://{args.address}:{port}", flush=True)
            await stop.wait()
            log.info("stopping")
    finally:
        ros.shutdown()
    return 0


def _read_secret(path: str | None) -> str | None:
    if path:
        with open(path, encoding="utf-8") as handle:
            secret = handle.read().strip()
        if not secret:
            raise SystemExit(f"caretaker bridge: {path} is empty; put the shared secret in it")
        return secret
    return os.environ.get(AUTH_SECRET_ENV) or None


def use_dds_profile() -> None:
    """Give Fast DDS the bridge's profile (:data:`DDS_PROFILE`) unless the operator names one.

    Fast DDS reads the variable when the first participant is created, so this runs before
    any ROS node exists; the bridge starts no child processes that would inherit it.
    """
    chosen = os.environ.get(DDS_PROFILE_ENV)
    if chosen:
        log.info("Fast DDS profile: %s (from %s; the bridge's own is not used)", chosen, DDS_PROFILE_ENV)
        return
    os.environ[DDS_PROFILE_ENV] = str(DDS_PROFILE)
    log.info("Fast DDS profile: %s", DDS_PROFILE)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``caretaker bridge``."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=args.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    use_dds_profile()
    try:
        with asyncio.Runner(loop_factory=uvloop.new_event_loop) as runner:
            return runner.run(run(args))
    except KeyboardInterrupt:
        return 0


if __name__ == "__main__":
    sys.exit(main())
