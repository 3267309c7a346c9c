"""The robot side's ROS parts load Caretaker's Fast DDS profile (python/caretaker/fastdds_parts.xml):
a service answers a caller discovered late instead of dropping the answer after Fast DDS's 100 ms.
An operator's own profile wins; commands that are no ROS part are left alone."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from caretaker import cli

NS = {"dds": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


@pytest.mark.parametrize("part", cli.ROS_PARTS)
def test_each_ros_part_loads_the_parts_profile(monkeypatch: pytest.MonkeyPatch, part: str) -> None:
    monkeypatch.delenv(cli.DDS_PROFILE_ENV, raising=False)
    monkeypatch.setattr(cli, "SUBCOMMANDS", {part: ("builtins", "len", "stands in for the part")})
    cli.main([part])  # len([]) stands in: only what main sets up before the part matters here
    assert cli.os.environ[cli.DDS_PROFILE_ENV] == str(cli.PARTS_DDS_PROFILE)


def test_an_operators_profile_wins_and_other_commands_are_left_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cli, "SUBCOMMANDS", {"sim": ("builtins", "len", ""), "lint": ("builtins", "len", "")})
    monkeypatch.setenv(cli.DDS_PROFILE_ENV, "/etc/ours.xml")
    cli.main(["sim"])
    assert cli.os.environ[cli.DDS_PROFILE_ENV] == "/etc/ours.xml"
    monkeypatch.delenv(cli.DDS_PROFILE_ENV)
    cli.main(["lint"])
    assert cli.DDS_PROFILE_ENV not in cli.os.environ


def test_the_profile_makes_every_writer_wait_five_seconds_for_a_late_reader() -> None:
    writer = ET.parse(cli.PARTS_DDS_PROFILE).getroot().find("dds:data_writer", NS)
    assert writer is not None and writer.get("is_default_profile") == "true"
    blocking = writer.find("dds:qos/dds:reliability/dds:max_blocking_time", NS)
    assert blocking is not None and blocking.findtext("dds:sec", namespaces=NS) == "5"
