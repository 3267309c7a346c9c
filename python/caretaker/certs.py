"""``caretaker certs DIR --host ADDRESS``: the keys and secret a ground and a habitat share over a link.

The link is wss:// with the bridge's HMAC authentication (docs/deployment.md). This makes, in
DIR, with the ``openssl`` command:

- ``ca.pem``, ``ca.key``: a certificate authority of your own (keep ``ca.key`` off both hosts
  once the bridge certificate is made; the ground needs ``ca.pem`` only);
- ``bridge.pem``, ``bridge.key``: the habitat's bridge certificate, signed by that CA, valid for
  every ``--host`` (IP addresses and DNS names the ground connects to: the habitat's address,
  and a relay's when the ground reaches it through one);
- ``rosbridge.secret``: the shared secret both sides authenticate with (never crosses the link).

Keys and the secret are readable by their owner only. Nothing is overwritten without ``--force``:
a new secret or CA locks out every host still holding the old one.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import secrets
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

__all__ = ["FILES", "CertsError", "main", "make_link_credentials"]

#: What :func:`make_link_credentials` writes, and who needs it.
FILES = {
    "ca.pem": "ground (security.ca_file of its binding)",
    "ca.key": "nobody once done: keep it offline to sign a new bridge certificate",
    "bridge.pem": "habitat (bridge.certfile of its deployment)",
    "bridge.key": "habitat (bridge.keyfile)",
    "rosbridge.secret": "both (bridge.auth_secret_file; security.secret_file of the ground binding)",
}


class CertsError(RuntimeError):
    """The credentials could not be made (openssl missing or failing, files in the way, bad host)."""


def _subject_alt_names(hosts: list[str]) -> str:
    names = []
    for host in hosts:
        try:
            names.append(f"IP:{ipaddress.ip_address(host)}")
        except ValueError:
            if not host or any(c in host for c in " ,=/\\"):
                raise CertsError(f"--host {host!r}: expected an IP address or a DNS name") from None
            names.append(f"DNS:{host}")
    return ",".join(names)


def make_link_credentials(folder: Path, hosts: list[str], *, days: int = 365, force: bool = False) -> dict[str, Path]:
    """Make the CA, the bridge certificate for ``hosts`` and the shared secret in ``folder``.

    Returns:
        file name → path, for every name of :data:`FILES`.

    Raises:
        CertsError: no hosts, a bad host, files already there (without ``force``), openssl failed.
    """
    if not hosts:
        raise CertsError("give at least one --host: the address the ground connects to")
    if shutil.which("openssl") is None:
        raise CertsError("the openssl command is not installed (apt-get install openssl)")
    san = _subject_alt_names(hosts)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {name: folder / name for name in FILES}
    present = [str(p) for p in paths.values() if p.exists()]
    if present and not force:
        raise CertsError(
            f"{', '.join(present)} already exist; --force replaces them (hosts holding the old ones "
            "are then locked out)"
        )
    with tempfile.TemporaryDirectory(prefix="caretaker-certs-") as scratch:
        work = Path(scratch)

        def openssl(*args: str) -> None:
            result = subprocess.run(["openssl", *args], cwd=work, capture_output=True, text=True, timeout=120)
            if result.returncode != 0:
                raise CertsError(f"openssl {args[0]} failed: {result.stderr.strip()}")

        openssl(
            "req",
            "-x509",
            "-newkey",
            "rsa:3072",
            "-nodes",
            "-keyout",
            "ca.key",
            "-out",
            "ca.pem",
            "-days",
            str(days),
            "-subj",
            "/CN=Caretaker link CA",
            "-addext",
            "basicConstraints=critical,CA:TRUE",
            "-addext",
            "keyUsage=critical,keyCertSign,cRLSign",
        )
        (work / "san.ext").write_text(f"subjectAltName={san}\nextendedKeyUsage=serverAuth\n")
        openssl(
            "req",
            "-newkey",
            "rsa:3072",
            "-nodes",
            "-keyout",
            "bridge.key",
            "-out",
            "bridge.csr",
            "-subj",
            f"/CN={hosts[0]}",
        )
        openssl(
            "x509",
            "-req",
            "-in",
            "bridge.csr",
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-days",
            str(days),
            "-out",
            "bridge.pem",
            "-extfile",
            "san.ext",
        )
        (work / "rosbridge.secret").write_text(secrets.token_urlsafe(32) + "\n")
        for name, path in paths.items():
            shutil.copyfile(work / name, path)
            os.chmod(path, 0o644 if name.endswith(".pem") else 0o600)
    return paths


def main(argv: list[str] | None = None) -> int:
    """``caretaker certs DIR --host ADDRESS...``; exit 1 with one line if they cannot be made."""
    parser = argparse.ArgumentParser(prog="caretaker certs", description=__doc__.splitlines()[0])
    parser.add_argument("folder", metavar="DIR", type=Path, help="where to write them (made if missing)")
    parser.add_argument(
        "--host",
        action="append",
        default=[],
        metavar="ADDRESS",
        help="an IP address or DNS name the ground connects to (repeatable)",
    )
    parser.add_argument("--days", type=int, default=365, help="validity of the certificates (default 365)")
    parser.add_argument("--force", action="store_true", help="replace files already there")
    args = parser.parse_args(argv)
    if args.days < 1:
        parser.error("--days must be at least 1")
    try:
        paths = make_link_credentials(args.folder, args.host, days=args.days, force=args.force)
    except CertsError as exc:
        print(f"caretaker certs: {exc}", file=sys.stderr)
        return 1
    for name, path in paths.items():
        print(f"{path}  → {FILES[name]}")
    return 0
