"""A link's credentials (``caretaker certs``) and the binding sections that use them (``link:``,
``security:``), checked without a JVM by ``caretaker check`` as the Java loader checks them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from caretaker.certs import CertsError, make_link_credentials
from caretaker.processes import REPO
from procedure_language.binding import BindingError, read_binding

GROUND = REPO / "sysrep" / "bindings" / "iva-ground.yaml"


def _ground_binding(folder: Path, **changes: object) -> Path:
    data = yaml.safe_load(GROUND.read_text())
    for system in data["systems"]:
        system["sysrep"] = str((GROUND.parent / system["sysrep"]).resolve())
    data.update(changes)
    path = folder / "ground.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _caretaker(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "caretaker.cli", *args], capture_output=True, text=True, timeout=120)


def test_certs_make_a_ca_a_bridge_certificate_for_every_host_and_a_secret(tmp_path: Path) -> None:
    made = _caretaker("certs", str(tmp_path / "link"), "--host", "10.77.2.2", "--host", "habitat.example")
    assert made.returncode == 0, made.stderr
    files = {p.name: p for p in (tmp_path / "link").iterdir()}
    assert set(files) == {"ca.pem", "ca.key", "bridge.pem", "bridge.key", "rosbridge.secret"}
    assert all(str(files[name]) in made.stdout for name in files)
    verified = subprocess.run(
        ["openssl", "verify", "-CAfile", str(files["ca.pem"]), str(files["bridge.pem"])],
        capture_output=True,
        text=True,
        check=False,
    )
    assert verified.returncode == 0, verified.stdout + verified.stderr
    san = subprocess.run(
        ["openssl", "x509", "-in", str(files["bridge.pem"]), "-noout", "-ext", "subjectAltName"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "IP Address:10.77.2.2" in san and "DNS:habitat.example" in san
    assert len(files["rosbridge.secret"].read_text().strip()) >= 32
    assert {oct(files[n].stat().st_mode & 0o777) for n in ("ca.key", "bridge.key", "rosbridge.secret")} == {"0o600"}
    again = _caretaker("certs", str(tmp_path / "link"), "--host", "10.77.2.2")
    assert again.returncode == 1 and "already exist; --force replaces them" in again.stderr
    with pytest.raises(CertsError, match="at least one --host"):
        make_link_credentials(tmp_path / "none", [])
    with pytest.raises(CertsError, match="expected an IP address or a DNS name"):
        make_link_credentials(tmp_path / "bad", ["a b"])


def test_a_ground_binding_states_its_link_and_security(tmp_path: Path) -> None:
    credentials = make_link_credentials(tmp_path / "link", ["10.77.1.1"], days=1)
    path = _ground_binding(tmp_path, security={"ca_file": "link/ca.pem", "secret_file": "link/rosbridge.secret"})
    binding = read_binding(path)
    assert binding.link.stated and binding.link.one_way_delay == 1.3 and binding.link.outage_budget == 120
    assert binding.security.ca_file == credentials["ca.pem"]
    assert binding.security.secret_file == credentials["rosbridge.secret"]
    loopback = read_binding(REPO / "sysrep" / "bindings" / "iva.yaml")
    assert not loopback.link.stated and loopback.security.ca_file is None
    checked = _caretaker("check", str(path))
    assert checked.returncode == 0, checked.stderr
    assert checked.stdout.strip() == f"{path}: ok (a binding)"


@pytest.mark.parametrize(
    ("changes", "problem"),
    [
        ({"link": {"one_way_delay": -1}}, "link.one_way_delay: "),
        ({"link": {"outage_budget": 0}}, "link.outage_budget: must be a positive number of seconds"),
        ({"link": {"delay": 1.3}}, "unknown key 'delay'"),
        ({"security": {"ca_file": "nowhere.pem"}}, "security.ca_file: no such file"),
        ({"security": {"ca_file": "secret"}}, "holds no PEM certificate"),
        ({"security": {"secret_file": "empty"}}, "is empty; put the bridge's shared secret in it"),
        ({"security": {"secret_file": "secret", "token_file": "secret"}}, "not both"),
    ],
)
def test_a_wrong_link_or_security_section_is_one_line_naming_the_key(
    tmp_path: Path, changes: dict[str, object], problem: str
) -> None:
    (tmp_path / "secret").write_text("s3cret\n")
    (tmp_path / "empty").write_text("\n")
    path = _ground_binding(tmp_path, **{"security": {}, **changes})
    with pytest.raises(BindingError, match=problem.replace(".", r"\.").replace("'", "'")) as error:
        read_binding(path)
    assert str(error.value).startswith(f"{path}:")
