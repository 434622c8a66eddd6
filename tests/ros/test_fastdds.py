"""The Fast DDS profile that gives ``bagkit record`` a large shared-memory receive queue."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bagkit.ros.fastdds import (
    PROFILES_FILE_VARIABLE,
    fast_dds,
    large_receive_queue,
    localhost_only,
    shared_memory_profile,
    user_middleware_setting,
)

NS = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def transports(profile: str) -> list[tuple[str, str | None, str | None]]:
    """(type, port_queue_capacity, segment_size) of each transport of the default profile."""
    root = ET.fromstring(profile)
    descriptors = {
        d.findtext("f:transport_id", namespaces=NS): d
        for d in root.iterfind(".//f:transport_descriptor", NS)
    }
    (participant,) = root.iterfind(".//f:participant", NS)
    assert participant.get("is_default_profile") == "true"
    assert participant.findtext(".//f:useBuiltinTransports", namespaces=NS) == "false"
    used = [t.text for t in participant.iterfind(".//f:userTransports/f:transport_id", NS)]
    return [
        (
            descriptors[name].findtext("f:type", namespaces=NS) or "",
            descriptors[name].findtext("f:port_queue_capacity", namespaces=NS),
            descriptors[name].findtext("f:segment_size", namespaces=NS),
        )
        for name in used
    ]


def test_profile_keeps_fast_dds_transports_with_a_larger_port() -> None:
    # rmw_fastrtps adds its own shared-memory and UDP transports for LOCALHOST, after ours.
    assert transports(shared_memory_profile(localhost=True, port_queue_capacity=4096)) == [
        ("SHM", "4096", None)
    ]
    assert transports(shared_memory_profile(localhost=False, segment_size=1 << 26)) == [
        ("SHM", "65536", str(1 << 26)),
        ("UDPv4", None, None),
    ]


@pytest.mark.parametrize("localhost", [True, False])
def test_profile_announces_the_participant_every_half_second(localhost: bool) -> None:
    root = ET.fromstring(shared_memory_profile(localhost=localhost))
    (period,) = root.iterfind(".//f:participant//f:discovery_config/f:leaseAnnouncement", NS)
    seconds = int(period.findtext("f:sec", namespaces=NS) or "x")
    nanoseconds = int(period.findtext("f:nanosec", namespaces=NS) or "x")
    assert seconds * 10**9 + nanoseconds == 500_000_000


@pytest.mark.parametrize(
    ("environ", "expected"),
    [
        ({}, False),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, False),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"}, False),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}, False),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, True),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "nonsense"}, True),  # rcl assumes localhost
        ({"ROS_LOCALHOST_ONLY": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, True),
    ],
)
def test_discovery_range_read_as_rcl_reads_it(environ: dict[str, str], expected: bool) -> None:
    assert localhost_only(environ) is expected


@pytest.mark.parametrize(
    ("rmw", "expected"),
    [
        (None, True),  # Jazzy's default
        ("", True),
        ("rmw_fastrtps_cpp", True),
        ("rmw_fastrtps_dynamic_cpp", True),
        ("rmw_cyclonedds_cpp", False),
        ("rmw_zenoh_cpp", False),
    ],
)
def test_fast_dds_is_the_default_middleware(rmw: str | None, expected: bool) -> None:
    assert fast_dds({} if rmw is None else {"RMW_IMPLEMENTATION": rmw}) is expected


def test_user_settings_win(tmp_path: Path) -> None:
    assert user_middleware_setting({}, tmp_path) is None
    assert user_middleware_setting({"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}, tmp_path) is None
    assert user_middleware_setting({"RMW_IMPLEMENTATION": ""}, tmp_path) is None
    assert user_middleware_setting({"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}, tmp_path) == (
        "RMW_IMPLEMENTATION=rmw_cyclonedds_cpp"
    )
    for name in (
        PROFILES_FILE_VARIABLE,
        "FASTDDS_DEFAULT_PROFILES_FILE",
        "FASTDDS_BUILTIN_TRANSPORTS",
    ):
        assert user_middleware_setting({name: "x"}, tmp_path) == f"${name}"
    (tmp_path / "DEFAULT_FASTRTPS_PROFILES.xml").write_text("<dds/>")
    assert user_middleware_setting({}, tmp_path) == str(tmp_path / "DEFAULT_FASTRTPS_PROFILES.xml")


def test_profile_file_exists_only_inside_the_block(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(Path(__file__).parent)
    environ = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    with large_receive_queue(environ, port_queue_capacity=2048) as applied:
        assert applied
        profile = Path(environ[PROFILES_FILE_VARIABLE])
        assert transports(profile.read_text()) == [("SHM", "2048", None)]
    assert environ == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    assert not profile.exists()

    mine = {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    with large_receive_queue(mine) as applied:
        assert not applied
        assert mine == {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
