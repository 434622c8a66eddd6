"""Fast DDS's files in tests: a user's own profile, and the shared-memory ports of this domain.

A port is a file under /dev/shm that outlives its process and is reused, at its old size, by
the next participant that gets the same port number: a test that reads a port's size first
removes the domain's ports that no live process listens on.
"""

from __future__ import annotations

import os
from pathlib import Path

SHM = Path("/dev/shm")
USER_PROFILE = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"><profiles>'
    '<participant profile_name="mine" is_default_profile="true"><rtps/></participant>'
    "</profiles></dds>\n"
)
_PORT_BASE, _PORTS_PER_DOMAIN = 7400, 250
_PREFIX = "fastrtps_port"


def environment(directory: Path, *, user_profile: bool) -> dict[str, str]:
    """This process's environment; with ``user_profile``, a default profile of the user's own
    (written in ``directory``), which bagkit must not override with its tuning."""
    env = dict(os.environ)
    if user_profile:
        mine = directory / "mine.xml"
        mine.write_text(USER_PROFILE)
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(mine)
    return env


def _domain_range() -> range:
    first = _PORT_BASE + _PORTS_PER_DOMAIN * int(os.environ["ROS_DOMAIN_ID"])
    return range(first, first + _PORTS_PER_DOMAIN)


def _port_of(link: str) -> int | None:
    """The port number of a listener's lock file (``/dev/shm/fastrtps_portN_el``)."""
    if not (link.startswith(f"{SHM}/{_PREFIX}") and link.endswith("_el")):
        return None
    number = link.removeprefix(f"{SHM}/{_PREFIX}").removesuffix("_el")
    return int(number) if number.isdigit() else None


def _listened(pid: int) -> set[int]:
    """The ports whose lock file ``pid`` holds open: the ones it listens on."""
    ports = set()
    try:
        descriptors = list(Path(f"/proc/{pid}/fd").iterdir())
    except OSError:  # gone, or not ours to read
        return ports
    for fd in descriptors:
        try:
            port = _port_of(os.readlink(fd))
        except OSError:  # closed meanwhile
            continue
        if port is not None:
            ports.add(port)
    return ports


def listened_port_sizes(pid: int) -> dict[int, int]:
    """Sizes of the ports in this domain that ``pid`` listens on.

    Not every port it maps: it also maps the ports of the participants it sends to. The few
    outside the domain's range (7000, 7001) are shared by every domain and sized by anyone.
    """
    domain = _domain_range()
    return {
        port: (SHM / f"{_PREFIX}{port}").stat().st_size for port in _listened(pid) if port in domain
    }


def remove_stale_ports() -> None:
    """Remove the files of this domain's ports that no live process listens on.

    The domain is this test process's alone (tests/domains.py), so no participant can be
    opening one of them meanwhile.
    """
    live: set[int] = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            live |= _listened(int(entry.name))
    for port in _domain_range():
        if port in live:
            continue
        for name in (f"{_PREFIX}{port}", f"{_PREFIX}{port}_el", f"sem.{_PREFIX}{port}_mutex"):
            (SHM / name).unlink(missing_ok=True)
