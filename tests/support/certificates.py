"""A self-signed certificate for 127.0.0.1, for tests of TLS on loopback."""

from __future__ import annotations

import subprocess
from pathlib import Path

from support.processes import COMMAND_HANG_S


def self_signed_certificate(folder: Path, cert_name: str = "cert.pem") -> tuple[Path, Path]:
    """Write a one-day certificate for 127.0.0.1 and its key into ``folder``; return both paths."""
    cert, key = folder / cert_name, folder / "key.pem"
    subprocess.run(
        [
            "openssl",
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-days",
            "1",
            "-subj",
            "/CN=127.0.0.1",
            "-addext",
            "subjectAltName=IP:127.0.0.1",
            "-keyout",
            str(key),
            "-out",
            str(cert),
        ],
        check=True,
        capture_output=True,
        timeout=COMMAND_HANG_S,
    )
    return cert, key
