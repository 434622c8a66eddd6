"""Definitions for bags that store none, from the type store of the ROS 2 distribution.

rosbag2 stores message definitions since Iron; a Foxy to Humble ``.db3`` holds none, and the
types changed between distributions (Humble's ``sensor_msgs/msg/Range`` has no ``variance``).
rosbags ships the types of each distribution: the bag's ``metadata.yaml`` names its
``ros_distro`` (from Iron on); otherwise Jazzy's are used, said once in a warning. The
``BAGKIT_DISTRO`` environment variable (the read commands' ``--distro``) overrides both.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterable

from bagkit.bag.errors import BagError
from bagkit.errors import SettingWarning

DISTRO_ENV = "BAGKIT_DISTRO"
DEFAULT_DISTRO = "jazzy"
DISTROS = ("foxy", "galactic", "humble", "iron", "jazzy", "kilted", "lyrical")
"""The distributions whose types rosbags ships (``rosbags.typesys.Stores.ROS2_<NAME>``)."""


class DistroDefinitionsWarning(SettingWarning):
    """A bag stores no definitions and names no known distribution: Jazzy's types are used."""


def check_distro(name: str) -> str:
    """``name`` in lower case.

    Raises:
        BagError: not one of :data:`DISTROS`.
    """
    distro = name.strip().lower()
    if distro not in DISTROS:
        raise BagError(f"unknown ROS 2 distribution {name!r} (choose from {', '.join(DISTROS)})")
    return distro


def distro_definitions(
    type_names: Iterable[str], ros_distro: str, override: str | None = None
) -> dict[str, str]:
    """The ``ros2msg`` definitions of ``type_names`` in the distribution's type store.

    Args:
        type_names: types the bag stores no definition of (``pkg/msg/Name``).
        ros_distro: what the bag's ``metadata.yaml`` names (``""`` when nothing).
        override: the distribution to use whatever the bag says (default: ``BAGKIT_DISTRO``).

    Types the store does not have are left out. Warns (once per call that finds types) when
    the bag names no known distribution and none is given.

    Raises:
        BagError: ``override`` names no known distribution.
    """
    wanted = sorted(set(type_names))
    if not wanted:
        return {}
    from rosbags.typesys import Stores, get_typestore

    override = override or os.environ.get(DISTRO_ENV) or None
    distro = check_distro(override) if override else ros_distro.strip().lower()
    guessed = distro not in DISTROS
    if guessed:
        distro = DEFAULT_DISTRO
    store = get_typestore(Stores[f"ROS2_{distro.upper()}"])
    found = {
        name: store.generate_msgdef(name, ros_version=2)[0]
        for name in wanted
        if name in store.fielddefs
    }
    if found and guessed:
        named = f"names ros_distro {ros_distro!r}" if ros_distro else "names no ros_distro"
        warnings.warn(
            DistroDefinitionsWarning(
                f"the bag stores no message definitions and {named}: decoding "
                f"{', '.join(sorted(found))} with ROS 2 {distro.capitalize()}'s",
                DISTRO_ENV,
            ),
            stacklevel=2,
        )
    return found
