"""The bridge's own Fast DDS profile: Fast DDS parses it, and an operator's profile replaces it."""

from __future__ import annotations

from pathlib import Path

from support.processes import caretaker

from .rosbridge_support import RawClient, bridge_url

PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"


def start_bridge(env: dict[str, str]) -> str:
    """Start a bridge, check it serves a rosapi call, stop it; return its whole output."""
    process = caretaker("bridge", "--port", "0", env=env)
    try:
        process.wait_ready(60)
        host, port = bridge_url(process).split("//")[1].rsplit(":", 1)
        client = RawClient(host, int(port))
        try:
            answer = client.request({"op": "call_service", "service": "/rosapi/get_time"}, "service_response")
            assert answer["result"] is True
        finally:
            client.close()
    finally:
        process.stop()
    return process.tail(400)


def test_the_bridge_loads_its_own_profile_and_fast_dds_accepts_it(ros_env: dict[str, str]) -> None:
    env = {k: v for k, v in ros_env.items() if k != PROFILE_ENV}
    output = start_bridge(env)
    assert "fastdds_profile.xml" in output
    assert "XMLPARSER" not in output, output


def test_an_operator_profile_replaces_the_bridges(ros_env: dict[str, str], tmp_path: Path) -> None:
    """A broken file of the operator's is what Fast DDS reads (and reports), not the bridge's."""
    mine = tmp_path / "operator.xml"
    mine.write_text(
        '<?xml version="1.0"?>\n<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">'
        '<data_writer profile_name="w" is_default_profile="true"><times><notATime/></times>'
        "</data_writer></profiles>\n"
    )
    output = start_bridge(dict(ros_env, **{PROFILE_ENV: str(mine)}))
    assert f"Error parsing '{mine}'" in output, output
    assert "fastdds_profile.xml" not in output
