"""Fast DDS settings for a recording process: a receive queue that a flood does not overflow.

Fast DDS delivers same-host samples through a shared-memory *port* per receiving participant, a
queue of 512 descriptors by default. A publisher flooding a topic fills it whenever the
receiving process is descheduled for a moment; the samples that do not fit are dropped by the
transport and repaired by the reliability protocol, and until the repair arrives Fast DDS 2.14
walks its set of out-of-order sequence numbers for every sample received
(``WriterProxy::unknown_missing_changes_up_to``). Measured with an Imu flood here: the receive
thread's CPU per message 16 - 25 us with the default queue, 5 - 6 us with 65536 descriptors, and
the rate of a counting subscriber 27 - 32k -> 58 - 68k msg/s.

The queue belongs to the participant that receives, so a recorder can size its own. Fast DDS
takes it from an XML profile, read once per process when the first participant is created:
:func:`large_receive_queue` provides one for the duration of a ``with`` block.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, MutableMapping
from pathlib import Path

PORT_QUEUE_CAPACITY = 65536
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


def localhost_only(environ: MutableMapping[str, str]) -> bool:
    """Whether ROS limits discovery to this host, as rcl reads the environment."""
    if environ.get("ROS_LOCALHOST_ONLY") == "1":
        return True
    return environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "") not in _RANGES_WITH_DEFAULT_TRANSPORTS


def receive_queue_profile(
    *, localhost: bool, port_queue_capacity: int = PORT_QUEUE_CAPACITY
) -> str:
    """A Fast DDS XML profile: Fast DDS's own transports, with a larger shared-memory port.

    Args:
        localhost: discovery is limited to this host. rmw_fastrtps then adds a shared-memory and
            a UDP transport of its own after the profile's, so the profile brings only the
            shared-memory one (the first to open the port sets its size). Otherwise the profile
            lists both transports of Fast DDS's default.
        port_queue_capacity: descriptors in the port (messages waiting to be read).
    """
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
        <type>SHM</type>
        <port_queue_capacity>{port_queue_capacity}</port_queue_capacity>
      </transport_descriptor>{udp_descriptor}
    </transport_descriptors>
    <participant profile_name="bagkit_record" is_default_profile="true">
      <rtps>
        <userTransports>
          <transport_id>bagkit_shm</transport_id>{udp_reference}
        </userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def user_middleware_setting(
    environ: MutableMapping[str, str], working_directory: Path | None = None
) -> str | None:
    """The user's own Fast DDS setting that bagkit must not override, or None."""
    for name in _USER_SETTINGS:
        if environ.get(name):
            return f"${name}"
    rmw = environ.get("RMW_IMPLEMENTATION", "")
    if rmw and not rmw.startswith("rmw_fastrtps"):
        return f"RMW_IMPLEMENTATION={rmw}"
    directory = working_directory or Path.cwd()
    for name in _USER_PROFILE_FILES:
        if (directory / name).is_file():
            return str(directory / name)
    return None


@contextlib.contextmanager
def large_receive_queue(
    environ: MutableMapping[str, str] | None = None,
    *,
    port_queue_capacity: int = PORT_QUEUE_CAPACITY,
) -> Iterator[bool]:
    """Give the DDS participants created inside the block a large shared-memory receive queue.

    Writes :func:`receive_queue_profile` to a temporary file and points
    ``FASTRTPS_DEFAULT_PROFILES_FILE`` at it until the block ends. Process-wide, and only for
    participants created in the block if none was created in the process before (Fast DDS reads
    its profile once): ``bagkit record`` opens it around the recording; the :class:`Recorder`
    class leaves its host process alone. Nothing changes where the user has a setting of their
    own (:func:`user_middleware_setting`).

    Args:
        environ: the environment to change (default: ``os.environ``).
        port_queue_capacity: descriptors in the port.

    Yields:
        Whether the profile is in effect.
    """
    env = os.environ if environ is None else environ
    if user_middleware_setting(env) is not None:
        yield False
        return
    with tempfile.TemporaryDirectory(prefix="bagkit-fastdds-") as directory:
        profile = Path(directory) / "bagkit_record.xml"
        profile.write_text(
            receive_queue_profile(
                localhost=localhost_only(env), port_queue_capacity=port_queue_capacity
            )
        )
        env[PROFILES_FILE_VARIABLE] = str(profile)
        try:
            yield True
        finally:
            env.pop(PROFILES_FILE_VARIABLE, None)
