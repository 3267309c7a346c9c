"""``caretaker interop ws[s]://HOST:PORT``: check a running rosbridge v2 server against docs/interop.md.

Prints one line per case and a summary table; exits 0 only if every case of the claimed profiles
is OK, NON-STRICT or INFORMATIONAL (1 otherwise, 2 for bad arguments or an unreachable server).
``caretaker interop --serve PORT --profile clients`` turns it round: a scripted rosbridge server
on PORT that checks a client (:mod:`interop.scripted_server`), with the same report.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import ssl
import sys
from pathlib import Path
from typing import NoReturn

from .catalog import DEFAULT_PROFILES, PROFILES, cases_of
from .outcome import CaseResult
from .report import case_line, passed, summary, to_json, write_report
from .runner import Target, run_cases
from .session import Credentials
from .wire import Recorder, WebSocket

__all__ = ["main"]

PROG = "caretaker interop"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{PROG}: {message} (see {PROG} --help)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("url", nargs="?", help="the server, ws://HOST:PORT or wss://HOST:PORT")
    parser.add_argument(
        "--serve",
        type=int,
        metavar="PORT",
        help="instead of checking a server, serve a scripted one on 127.0.0.1:PORT that checks a client "
        "(profile clients; docs/interop.md, Clients)",
    )
    parser.add_argument(
        "--profile",
        default="",
        help=f"profiles the server claims, comma-separated, or 'all' (default: {','.join(DEFAULT_PROFILES)}, "
        "plus auth with --secret-file); known: " + ", ".join(PROFILES),
    )
    parser.add_argument("--secret-file", type=Path, help="the server's shared secret (first line): HMAC auth")
    parser.add_argument("--ca", type=Path, help="PEM CA bundle that verifies a wss:// server's certificate")
    parser.add_argument("--report", type=Path, help="write index.json and index.html into this directory")
    parser.add_argument("--name", help="the server's name in the report (default: the URL)")
    parser.add_argument(
        "--link-delay", type=float, default=0.0, help="one-way delay of a link to the server, s (waits grow by it)"
    )
    parser.add_argument("--outage", type=float, default=0.0, help="longest outage of that link, s (waits grow by it)")
    parser.add_argument(
        "--quiet", type=float, default=30.0, help="how long the link profile's quiet client reads nothing, s (1-60)"
    )
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    return parser


def _profiles(text: str, have_secret: bool) -> tuple[str, ...]:
    if not text:
        return (*DEFAULT_PROFILES, "auth") if have_secret else DEFAULT_PROFILES
    if text == "all":
        return PROFILES if have_secret else DEFAULT_PROFILES
    names = tuple(dict.fromkeys(name.strip() for name in text.split(",") if name.strip()))
    unknown = [name for name in names if name not in PROFILES]
    if unknown:
        raise ValueError(f"unknown profile {unknown[0]!r}; known: {', '.join(PROFILES)}")
    if "auth" in names and not have_secret:
        raise ValueError("the auth profile needs --secret-file (the server's secret)")
    return names


def _secret(path: Path) -> str:
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise ValueError(f"cannot read the secret file {path}: {error}") from None
    if not lines or not lines[0].strip():
        raise ValueError(f"{path}:1: the secret file is empty")
    return lines[0].strip()


def _ssl_context(url: str, ca: Path | None) -> ssl.SSLContext | None:
    if not url.startswith("wss://"):
        if ca is not None:
            raise ValueError("--ca is for wss:// servers")
        return None
    try:
        return ssl.create_default_context(cafile=str(ca) if ca else None)
    except (OSError, ssl.SSLError) as error:
        raise ValueError(f"cannot load the CA bundle {ca}: {error}") from None


async def _reachable(target: Target) -> str | None:
    """None if a WebSocket opens to the target, else why not."""
    try:
        socket = await asyncio.wait_for(
            WebSocket.connect(target.url, Recorder(), "probe", ssl_context=target.ssl_context), 20
        )
    except (OSError, TimeoutError, ConnectionError, ssl.SSLError) as error:
        return str(error) or type(error).__name__
    await socket.close()
    return None


async def _run(target: Target, profiles: tuple[str, ...], quiet: bool) -> list[CaseResult] | str:
    why = await _reachable(target)
    if why is not None:
        return why

    def show(result: CaseResult) -> None:
        if not quiet:
            print(case_line(result), flush=True)

    return await run_cases(cases_of(profiles), target, show)


def main(argv: list[str]) -> int:
    """Run the suite against one server (see the module docstring)."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.serve is not None:
        if args.url:
            why = "give a server's URL to check it, or --serve PORT to check a client, not both"
            print(f"{PROG}: {why}", file=sys.stderr)
            return 2
        from .scripted_server import serve_main

        claimed = [name.strip() for name in args.profile.split(",") if name.strip()] or ["clients"]
        return serve_main(args.serve, claimed, args.report, args.json)
    try:
        if not args.url:
            raise ValueError("give the server's URL (ws://HOST:PORT or wss://HOST:PORT), or --serve PORT")
        if not args.url.startswith(("ws://", "wss://")):
            raise ValueError(f"not a ws:// or wss:// URL: {args.url!r}")
        credentials = Credentials(_secret(args.secret_file)) if args.secret_file else None
        profiles = _profiles(args.profile, credentials is not None)
        if not 0 <= args.link_delay <= 60 or not 0 <= args.outage <= 600 or not 1 <= args.quiet <= 60:
            raise ValueError("--link-delay must be 0-60 s, --outage 0-600 s, --quiet 1-60 s")
        target = Target(
            args.url,
            _ssl_context(args.url, args.ca),
            credentials,
            one_way_delay=args.link_delay,
            outage=args.outage,
            quiet=args.quiet,
        )
    except ValueError as error:
        print(f"{PROG}: {error}", file=sys.stderr)
        return 2
    outcome = asyncio.run(_run(target, profiles, args.json))
    if isinstance(outcome, str):
        print(f"{PROG}: cannot open a WebSocket to {args.url}: {outcome}", file=sys.stderr)
        return 2
    results = outcome
    server = args.name or args.url
    if args.json:
        print(json.dumps(to_json(server, results), indent=1))
    else:
        print()
        print(summary(results, profiles))
    if args.report:
        page = write_report(args.report, server, results)
        if not args.json:
            print(f"report: {page}")
    return 0 if passed(results, profiles) else 1
