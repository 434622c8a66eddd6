"""Fast DDS shared-memory settings for floods: a recorder's receive queue, a publisher's buffers.

Fast DDS moves same-host samples through shared memory: the publisher writes each into a buffer
of its segment and pushes a descriptor into the receiving participant's *port*, a queue of the
receiver's ``port_queue_capacity`` descriptors (512 by default). The same setting in the
publisher's profile sizes, as we read Fast DDS, its pool of send buffers; measured is that it
matters (figures below). In a flood either runs out whenever the subscriber falls a few
milliseconds behind; the samples that do not make it are repaired by the reliability
protocol, and meanwhile (as we read Fast DDS 2.14 and its perf profile) the receive thread walks
its set of out-of-order sequence numbers for every sample received
(``WriterProxy::unknown_missing_changes_up_to``). Both sides large is what lifts the Imu flood of
``benchmarks record`` (benchmarks/README.md, "Measurements behind the code").

The receive queue belongs to the recorder, which sizes its own with :func:`large_receive_queue`;
the send buffers belong to the publishing processes, which need a profile of their own
(:func:`shared_memory_profile` writes one; docs/record.md explains where it goes). Fast DDS
reads a profile once per process, when the first participant is created.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Mapping, MutableMapping
from pathlib import Path

PORT_QUEUE_CAPACITY = 65536
# Fast DDS's shared-memory segment when a profile does not say (512 KiB): a sender whose samples
# do not fit in it falls back to UDP fragments, which lose whole frames (issue 27: a 640x480
# rgb8 replay delivered 61 of 95 frames at --rate 1). A sender sizes its segment for
# SEGMENT_SAMPLES of its largest messages in flight, a power of two, at most MAX_SEGMENT_SIZE.
DEFAULT_SEGMENT_SIZE = 512 << 10
SEGMENT_SAMPLES = 16
MAX_SEGMENT_SIZE = 256 << 20
# How often the participant announces itself (Fast DDS: every 3 s). A participant answers a new
# one's first announcement at once, but Fast DDS 2.14 sends that first announcement before it
# listens (``RTPSParticipantImpl::enable``), so the answer is often lost and the newcomer finds
# the older participant only at its next periodic announcement: a publisher that starts while
# ``bagkit record`` runs (or a subscriber while ``bagkit play`` does) waited up to 3 s for its
# first match (benchmarks/README.md, "Replay and record start").
ANNOUNCEMENT_PERIOD_NS = 500_000_000
PROFILES_FILE_VARIABLE = "FASTRTPS_DEFAULT_PROFILES_FILE"
# Where Fast DDS 2.x looks for a profile of the user's: these variables, then these files in the
# working directory. FASTDDS_BUILTIN_TRANSPORTS is the user choosing the transports.
_USER_SETTINGS = (
    PROFILES_FILE_VARIABLE,
    "FASTDDS_DEFAULT_PROFILES_FILE",
    "FASTDDS_BUILTIN_TRANSPORTS",
)
_USER_PROFILE_FILES = ("DEFAULT_FASTRTPS_PROFILES.xml", "DEFAULT_FASTDDS_PROFILES.xml")
# ROS_AUTOMATIC_DISCOVERY_RANGE values with which rmw_fastrtps leaves the transports to Fast DDS
# (and so to the profile); rcl reads any other value, and ROS_LOCALHOST_ONLY=1, as LOCALHOST.
_RANGES_WITH_DEFAULT_TRANSPORTS = ("", "SUBNET", "SYSTEM_DEFAULT", "OFF")


def localhost_only(environ: Mapping[str, str]) -> bool:
    """Whether ROS limits discovery to this host, as rcl reads the environment."""
    if environ.get("ROS_LOCALHOST_ONLY") == "1":
        return True
    return environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "") not in _RANGES_WITH_DEFAULT_TRANSPORTS


def shared_memory_profile(
    *,
    localhost: bool,
    port_queue_capacity: int = PORT_QUEUE_CAPACITY,
    segment_size: int | None = None,
) -> str:
    """A Fast DDS XML profile: Fast DDS's own transports, with a larger shared-memory transport,
    and announcements every :data:`ANNOUNCEMENT_PERIOD_NS`.

    Args:
        localhost: discovery is limited to this host. rmw_fastrtps then adds a shared-memory and
            a UDP transport of its own after the profile's, so the profile brings only the
            shared-memory one (the first transport to open a port sets its size). Otherwise the
            profile lists both transports of Fast DDS's default.
        port_queue_capacity: descriptors in the receive port, and buffers in the send pool.
        segment_size: bytes of the send segment (Fast DDS's default: 512 KiB).
    """
    segment = (
        ""
        if segment_size is None
        else f"""
        <segment_size>{segment_size}</segment_size>"""
    )
    udp_descriptor = udp_reference = ""
    if not localhost:
        udp_descriptor = """
      <transport_descriptor>
        <transport_id>bagkit_udp</transport_id>
        <type>UDPv4</type>
      </transport_descriptor>"""
        udp_reference = """
          <transport_id>bagkit_udp</transport_id>"""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>bagkit_shm</transport_id>
        <type>SHM</type>{segment}
        <port_queue_capacity>{port_queue_capacity}</port_queue_capacity>
      </transport_descriptor>{udp_descriptor}
    </transport_descriptors>
    <participant profile_name="bagkit_shared_memory" is_default_profile="true">
      <rtps>
        <userTransports>
          <transport_id>bagkit_shm</transport_id>{udp_reference}
        </userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
        <builtin>
          <discovery_config>
            <leaseAnnouncement>
              <sec>{ANNOUNCEMENT_PERIOD_NS // 1_000_000_000}</sec>
              <nanosec>{ANNOUNCEMENT_PERIOD_NS % 1_000_000_000}</nanosec>
            </leaseAnnouncement>
          </discovery_config>
        </builtin>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def fast_dds(environ: Mapping[str, str]) -> bool:
    """Whether ROS runs on Fast DDS (rmw_fastrtps, Jazzy's default middleware)."""
    return (environ.get("RMW_IMPLEMENTATION") or "rmw_fastrtps_cpp").startswith("rmw_fastrtps")


def user_middleware_setting(
    environ: MutableMapping[str, str], working_directory: Path | None = None
) -> str | None:
    """The user's own Fast DDS setting that bagkit must not override, or None."""
    for name in _USER_SETTINGS:
        if environ.get(name):
            return f"${name}"
    if not fast_dds(environ):
        return f"RMW_IMPLEMENTATION={environ['RMW_IMPLEMENTATION']}"
    directory = working_directory or Path.cwd()
    for name in _USER_PROFILE_FILES:
        if (directory / name).is_file():
            return str(directory / name)
    return None


def segment_size_for(largest_message: int) -> int | None:
    """The shared-memory segment a sender of messages up to ``largest_message`` bytes needs.

    None when Fast DDS's default holds :data:`SEGMENT_SAMPLES` of them.
    """
    wanted = SEGMENT_SAMPLES * max(largest_message, 0)
    if wanted <= DEFAULT_SEGMENT_SIZE:
        return None
    return min(1 << (wanted - 1).bit_length(), MAX_SEGMENT_SIZE)


@contextlib.contextmanager
def large_receive_queue(
    environ: MutableMapping[str, str] | None = None,
    *,
    port_queue_capacity: int = PORT_QUEUE_CAPACITY,
    segment_size: int | None = None,
) -> Iterator[bool]:
    """Give the DDS participants created inside the block a large shared-memory receive queue.

    Writes :func:`shared_memory_profile` to a temporary file and points
    ``FASTRTPS_DEFAULT_PROFILES_FILE`` at it until the block ends. Process-wide, and only for
    participants created in the block if none was created in the process before (Fast DDS reads
    its profile once): :func:`bagkit.native.process_tuning` opens it around the creation
    of the recorder's and the player's node. Nothing changes where the user has a setting of their
    own (:func:`user_middleware_setting`).

    Args:
        environ: the environment to change (default: ``os.environ``).
        port_queue_capacity: descriptors in the port.
        segment_size: bytes of the shared-memory segment the participants send from (the
            player's, :func:`segment_size_for`); None: Fast DDS's default.

    Yields:
        Whether the profile is in effect.
    """
    env = os.environ if environ is None else environ
    if user_middleware_setting(env) is not None:
        yield False
        return
    with tempfile.TemporaryDirectory(prefix="bagkit-fastdds-") as directory:
        profile = Path(directory) / "bagkit_record.xml"
        try:
            profile.write_text(
                shared_memory_profile(
                    localhost=localhost_only(env),
                    port_queue_capacity=port_queue_capacity,
                    segment_size=segment_size,
                )
            )
        except OSError:
            # A full disk: the participant runs with Fast DDS's defaults (the bag will say more).
            yield False
            return
        env[PROFILES_FILE_VARIABLE] = str(profile)
        try:
            yield True
        finally:
            env.pop(PROFILES_FILE_VARIABLE, None)
