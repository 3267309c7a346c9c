"""``caretaker bridge``: the rosbridge v2 WebSocket server on rclpy.

One asyncio thread owns every WebSocket (:mod:`.framing`, :mod:`.session`); ROS runs on its
own threads (:mod:`.ros_thread`).  Prints ``READY bridge ws://HOST:PORT`` (the actual port,
also with ``--port 0``) once it accepts connections.  Loopback only unless ``--address`` says
otherwise, and a non-loopback address needs TLS and a secret (or ``--insecure``).  Options for
TLS, allow-lists, origins, quotas, keepalive and authentication are described in
docs/rosbridge.md and :mod:`.security`, :mod:`.limits`.
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import ipaddress
import json
import logging
import os
import re
import resource
import signal
import ssl
import sys
from collections import OrderedDict
from pathlib import Path
from typing import Any

import uvloop
from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from .actions import Actions
from .framing import BridgeConnection, ConnectionGate
from .limits import Limits, Quotas
from .operations import Bridge
from .protocol import CLOSE_POLICY_VIOLATION, Refused
from .ros_thread import NODE_NAME, RosThread
from .security import BRIDGE_SERVICES, AllowList, Authenticator, Policy
from .services import Services
from .session import ClientLog, OutputBudget, Session, SessionState
from .topics import Topics

log = logging.getLogger("bridge.rosbridge")

AUTH_SECRET_ENV = "CARETAKER_BRIDGE_SECRET"
DDS_PROFILE = Path(__file__).with_name("fastdds_profile.xml")
DDS_PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
FD_RESERVE = 256
"""File descriptors kept for DDS, logs and the like, beyond connections and subscriptions."""
PEER_LOGS = 1024
"""Connection log budgets kept (one per client address)."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="caretaker bridge", description="rosbridge v2 server on rclpy")
    parser.add_argument("--address", default="127.0.0.1", help="interface to bind (default: loopback only)")
    parser.add_argument("--port", type=int, default=9090, help="TCP port; 0 picks a free one (default 9090)")
    parser.add_argument("--certfile", help="TLS certificate (PEM); with --keyfile serves wss://")
    parser.add_argument("--keyfile", help="TLS private key (PEM)")
    parser.add_argument(
        "--auth-secret-file",
        help=f"file holding the shared secret clients must authenticate with "
        f"(or set {AUTH_SECRET_ENV}); see docs/rosbridge.md",
    )
    parser.add_argument(
        "--insecure", action="store_true", help="allow a non-loopback --address without TLS and a secret"
    )
    parser.add_argument(
        "--topics-glob",
        action="append",
        default=[],
        metavar="GLOB",
        help="allow only matching topics (repeatable; default: all)",
    )
    parser.add_argument(
        "--services-glob",
        action="append",
        default=[],
        metavar="GLOB",
        help="allow only matching services (repeatable; /rosapi/* and /rosbridge/* stay allowed)",
    )
    parser.add_argument(
        "--ready-services",
        action="append",
        default=[],
        metavar="GLOB",
        help="keep a client matched with every service matching GLOB from the moment it appears, "
        "so its first call does not wait for discovery (repeatable; e.g. '*/halt')",
    )
    parser.add_argument(
        "--actions-glob",
        action="append",
        default=[],
        metavar="GLOB",
        help="allow only matching actions (repeatable; default: all)",
    )
    parser.add_argument(
        "--params-glob",
        action="append",
        default=[],
        metavar="GLOB",
        help="allow reading only matching parameters, as /node:name (repeatable; default: all)",
    )
    parser.add_argument(
        "--set-params-glob",
        action="append",
        default=[],
        metavar="GLOB",
        help="allow setting matching parameters, as /node:name (repeatable; default: none)",
    )
    parser.add_argument(
        "--allow-origin",
        action="append",
        default=[],
        metavar="ORIGIN",
        help="accept browser connections from this Origin, e.g. https://console.example:8443 "
        "(repeatable; default: only clients that send no Origin)",
    )
    parser.add_argument(
        "--service-timeout",
        type=float,
        default=10.0,
        help="default call_service timeout in seconds when a call gives none (default 10)",
    )
    parser.add_argument(
        "--node-name",
        default=NODE_NAME,
        type=_node_name,
        help=f"the bridge's ROS node name (default {NODE_NAME}); each bridge on one ROS domain needs its own, "
        "or parameter reads and calls to its services reach whichever answers first",
    )
    parser.add_argument("--log-level", default="INFO")
    Limits.add_options(parser)
    args = parser.parse_args(argv)
    if bool(args.certfile) != bool(args.keyfile):
        parser.error("--certfile and --keyfile go together")
    if not _loopback(args.address) and not args.insecure:
        missing = [
            what
            for what, given in (
                ("TLS (--certfile/--keyfile)", args.certfile),
                (
                    f"secret (--auth-secret-file or {AUTH_SECRET_ENV})",
                    args.auth_secret_file or os.environ.get(AUTH_SECRET_ENV),
                ),
            )
            if not given
        ]
        if missing:
            parser.error(
                f"--address {args.address} is reachable from other hosts, but the bridge has no "
                f"{' and no '.join(missing)}; give them, or --insecure if this network is trusted"
            )
    return args


def _node_name(text: str) -> str:
    """A ROS node name: a letter or '_' first, then letters, digits and '_' (no namespace)."""
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]{0,254}", text):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a ROS node name: letters, digits and '_', not starting with a digit, "
            "e.g. rosbridge_habitat"
        )
    return text


def _loopback(address: str) -> bool:
    if address == "localhost":
        return True
    try:
        return ipaddress.ip_address(address).is_loopback
    except ValueError:  # a host name: it may resolve to any interface
        return False


class RosbridgeServer:
    """The WebSocket side: admits connections and runs one :class:`Session` per client."""

    def __init__(self, bridge: Bridge, auth_secret: str | None, limits: Limits) -> None:
        self.bridge = bridge
        self.authenticator = Authenticator(auth_secret, max_age=limits.login_max_age) if auth_secret else None
        self.limits = limits
        self.budget = OutputBudget(limits.max_total_queued_bytes)
        self.gate = ConnectionGate(2 * limits.max_connections)
        self.sessions: set[Session] = set()
        self._peer_logs: OrderedDict[str, ClientLog] = OrderedDict()

    def make_connection(self, *args: Any, **kwargs: Any) -> BridgeConnection:
        """websockets' connection factory: a :class:`BridgeConnection` under this server's gate."""
        connection = BridgeConnection(*args, **kwargs)
        connection.gate = self.gate
        connection.on_no_request = self._no_request
        return connection

    def _no_request(self, connection: BridgeConnection) -> None:
        after_tls = " after the TLS handshake" if connection.transport.get_extra_info("ssl_object") else ""
        self._peer_log(connection)(
            logging.WARNING,
            f"dropped after {self.limits.handshake_timeout:g} s (--handshake-timeout) without its WebSocket "
            f"upgrade request: {connection.traffic.bytes_received} bytes of it came{after_tls}",
        )

    def process_request(self, connection: ServerConnection, request: Request) -> Response | None:
        """Refuse a WebSocket handshake beyond ``--max-connections`` (HTTP 503)."""
        if len(self.sessions) < self.limits.max_connections:
            return None
        self._peer_log(connection)(
            logging.WARNING,
            f"refused: {len(self.sessions)} clients connected (--max-connections {self.limits.max_connections})",
        )
        return connection.respond(503, "The bridge serves as many clients as it may (--max-connections).\n")

    def _peer_log(self, connection: ServerConnection) -> ClientLog:
        address = str(connection.remote_address[0]) if connection.remote_address else "?"
        peer_log = self._peer_logs.pop(address, None) or ClientLog(f"clients from {address}")
        self._peer_logs[address] = peer_log
        while len(self._peer_logs) > PEER_LOGS:
            self._peer_logs.popitem(last=False)
        return peer_log

    async def connection(self, websocket: BridgeConnection) -> None:
        session = Session(websocket, authenticated=self.authenticator is None, limits=self.limits, budget=self.budget)
        self.sessions.add(session)
        peer_log = self._peer_log(websocket)
        peer_log(
            logging.INFO, f"client {session.number} connected from {session.peer} ({len(self.sessions)} connected)"
        )
        handle = functools.partial(self.bridge.handle_frame, session)
        websocket.on_backlog = session.backlog_changed
        try:
            if session.state is SessionState.AUTHENTICATING and not await self._authenticate(session):
                return
            websocket.on_text = handle
            async for frame in websocket:
                websocket.message_read()
                await websocket.reading_allowed.wait()  # backpressure in websockets' own framing too
                handle(frame)
        except ConnectionClosed:
            pass
        finally:
            websocket.on_text = None
            websocket.on_backlog = None
            session.mark_closed()
            self.sessions.discard(session)
            self.bridge.drop_session(session)
            traffic = session.traffic
            peer_log(
                logging.INFO,
                f"client {session.number} disconnected after {traffic.as_dict()['connected_s']} s: "
                f"{traffic.bytes_received} bytes in, {traffic.bytes_sent} out, "
                f"{traffic.messages_received} messages in, {traffic.messages_sent} out "
                f"({len(self.sessions)} connected)",
            )

    async def _authenticate(self, session: Session) -> bool:
        """Read the first message within ``--auth-timeout``; True if it authenticates."""
        websocket = session.websocket
        try:
            async with asyncio.timeout(self.limits.auth_timeout):
                frame = await websocket.recv()
            websocket.message_read()
            try:
                message: Any = json.loads(frame) if isinstance(frame, str) else None
            except (ValueError, RecursionError):
                message = None
            assert self.authenticator is not None
            self.authenticator.check(message)
        except TimeoutError:
            reason = f"no auth message within {self.limits.auth_timeout:g} s"
        except Refused as exc:
            reason = str(exc)
        else:
            session.state = SessionState.OPEN
            return True
        session.log(logging.WARNING, f"refused: {reason}")
        await websocket.close(CLOSE_POLICY_VIOLATION, reason[:120])
        return False


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
    limits = Limits.from_args(args)
    _raise_fd_limit(limits)
    ros = RosThread(loop, args.node_name)
    try:
        policy = Policy(
            AllowList("topic", tuple(args.topics_glob)),
            AllowList("service", tuple(args.services_glob), always=BRIDGE_SERVICES),
            AllowList("action", tuple(args.actions_glob)),
            AllowList("parameter", tuple(args.params_glob)),
            AllowList("parameter change", tuple(args.set_params_glob) or ("",)),
        )
        quotas = Quotas(limits)
        topics = Topics(ros, quotas)
        services = Services(ros, args.service_timeout, quotas, policy, tuple(args.ready_services))
        ready = asyncio.get_running_loop().create_task(services.keep_ready())
        actions = Actions(ros, policy.actions, quotas, services.graph)
        server = RosbridgeServer(Bridge(topics, services, actions, policy, limits, quotas), secret, limits)
        origins: list[Any] = [None, *args.allow_origin]  # None: clients that send no Origin
        handler: Any = server.connection  # takes the BridgeConnection that make_connection creates
        factory: Any = server.make_connection
        # the TLS handshake has the same limit (asyncio's own is 60 s): round trips of a long link
        handshake: dict[str, Any] = {"ssl_handshake_timeout": limits.handshake_timeout} if tls else {}
        async with serve(
            handler,
            args.address,
            args.port,
            ssl=tls,
            open_timeout=limits.handshake_timeout,
            **handshake,
            max_size=limits.max_message_size,
            compression=None,
            ping_interval=limits.ping_interval or None,
            ping_timeout=limits.ping_timeout or None,
            origins=origins,
            process_request=server.process_request,
            create_connection=factory,
        ) as ws_server:
            port = ws_server.sockets[0].getsockname()[1]
            # rosbridge's own launch tests read the bound port from this parameter
            ros.node.declare_parameter("actual_port", port)
            scheme = "wss" if tls else "ws"
            print(f"READY bridge {scheme}://{args.address}:{port}", flush=True)
            await stop.wait()
            log.info("stopping")
            ready.cancel()
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


def _raise_fd_limit(limits: Limits) -> None:
    """Raise the soft file-descriptor limit to the hard one, and say so if connections and
    subscriptions (one eventfd each) could still exhaust it: then new connections would fail."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != hard:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    needed = 2 * limits.max_connections + limits.max_total_subscriptions + FD_RESERVE
    if hard != resource.RLIM_INFINITY and hard < needed:
        log.warning(
            "only %d file descriptors allowed, but the limits may need %d: lower --max-connections or "
            "--max-total-subscriptions, or raise the limit (ulimit -n)",
            hard,
            needed,
        )


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
    logging.basicConfig(
        level=args.log_level.upper(), stream=sys.stderr, format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    # websockets logs every connection opened, closed or rejected; the bridge's own lines say the
    # same, rate-limited per client address
    logging.getLogger("websockets").setLevel(max(logging.WARNING, logging.getLogger().level))
    use_dds_profile()
    try:
        with asyncio.Runner(loop_factory=uvloop.new_event_loop) as runner:
            return runner.run(run(args))
    except KeyboardInterrupt:
        return 0


if __name__ == "__main__":
    sys.exit(main())
