"""The ``caretaker`` command: one entry point that starts any part of the system.

Each subcommand lives with its part (docs/interfaces.md) and is imported only when used, so
``caretaker lint`` never loads rclpy and ``caretaker sim`` never loads the JVM.
"""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path

__all__ = ["SUBCOMMANDS", "main"]

#: subcommand -> (module, function, one-line help). Each function takes argv and returns an exit code.
SUBCOMMANDS: dict[str, tuple[str, str, str]] = {
    "sim": ("sim.sim_node", "main", "run the pybullet simulation node (--scene FILE|iva|eva)"),
    "planner": ("at_ros.planner_node", "main", "run the OMPL planner node (--robot NAME|FILE)"),
    "at-server": ("at_ros.at_server", "main", "run the Affordance Template server (--robot NAME|FILE)"),
    "perception": ("perception.perception_node", "main", "run the perception node (perception/locate from markers)"),
    "bridge": ("bridge.rosbridge.server", "main", "run the rosbridge v2 server"),
    "ledger": ("bridge.ledger.main", "main", "run the habitat's command ledger (--state-dir DIR)"),
    "onboard": ("onboard.onboard_server", "main", "run the habitat's onboard executive (--bridge URL --binding FILE)"),
    "lint": ("caretaker.procedure_commands", "lint_main", "check procedures against their schema and SysReps"),
    "run": ("caretaker.procedure_commands", "run_main", "run a procedure with PAX (--auto|--manual)"),
    "release": ("caretaker.release_commands", "release_main", "release a procedure's version (--user A --approver B)"),
    "releases": ("caretaker.release_commands", "releases_main", "list the released procedure versions (list)"),
    "supervise": (
        "caretaker.supervise_command",
        "main",
        "keep the habitat's session open and supervise the onboard runs handed to it (--binding FILE)",
    ),
    "report": ("caretaker.procedure_commands", "report_main", "write the after-action report of a run"),
    "db": ("caretaker.procedure_commands", "db_main", "create or upgrade the audit log's schema (status: revision)"),
    "serve": ("console.server", "main", "serve the operator web view"),
    "accounts": ("console.accounts_command", "main", "add, change, remove and list the web view's accounts"),
    "agent": ("agent.mcp_server", "main", "serve an assistant over MCP as an agent account (CARETAKER_AGENT_TOKEN)"),
    "up": ("caretaker.stack", "up_main", "start a robot side and its rosbridge server (DEPLOYMENT)"),
    "demo": ("caretaker.demo", "demo_main", "run a deployment's demonstration end to end (DEPLOYMENT)"),
    "check": ("caretaker.check", "main", "check data files (scenes, robots, templates, deployments, procedures...)"),
    "new": ("caretaker.scaffold", "main", "write a working robot folder from a URDF, or a template skeleton"),
    "link": ("caretaker.link.cli", "main", "emulate a long, lossy ground-habitat link (--delay 1.3 ...)"),
    "certs": ("caretaker.certs", "main", "make the CA, bridge certificate and secret of a link (DIR --host ADDR)"),
    "interop": ("interop.cli", "main", "check a rosbridge v2 server against docs/interop.md (ws[s]://HOST:PORT)"),
}


#: Subcommands that serve ROS services on the robot side. They load :data:`PARTS_DDS_PROFILE`
#: unless the operator names a profile of their own (the bridge loads its own, see docs/rosbridge.md).
ROS_PARTS = ("sim", "perception", "planner", "at-server", "ledger")
PARTS_DDS_PROFILE = Path(__file__).with_name("fastdds_parts.xml")
DDS_PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"


def _usage() -> str:
    width = max(map(len, SUBCOMMANDS))
    lines = ["usage: caretaker COMMAND [ARGS...]", "", "commands:"]
    lines += [f"  {name.ljust(width)}  {help_}" for name, (_, _, help_) in SUBCOMMANDS.items()]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``caretaker COMMAND ARGS...`` to the part that implements COMMAND."""
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] in ("-h", "--help"):
        print(_usage())
        return 0 if args else 2
    name, rest = args[0], args[1:]
    if name not in SUBCOMMANDS:
        print(f"caretaker: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    module_name, function_name, _ = SUBCOMMANDS[name]
    if name in ROS_PARTS:  # before rclpy exists: Fast DDS reads it when its first participant is made
        os.environ.setdefault(DDS_PROFILE_ENV, str(PARTS_DDS_PROFILE))
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            print(f"caretaker: {name!r} is not available in this checkout ({module_name} is missing)", file=sys.stderr)
            return 2
        raise
    try:
        return int(getattr(module, function_name)(rest) or 0)
    except KeyboardInterrupt:  # Ctrl-C (or a supervisor's SIGINT) where a command has no handler of its own
        print(f"caretaker {name}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
