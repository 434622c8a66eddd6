"""Humble-era ``.db3`` bags as Foxy to Humble recorded them: no stored definitions, a
``ros_distro`` or none, /sonar ``sensor_msgs/msg/Range`` without Jazzy's ``variance``."""

from __future__ import annotations

import re
import sqlite3
from pathlib import Path

from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

HUMBLE = get_typestore(Stores.ROS2_HUMBLE)
RANGE = "sensor_msgs/msg/Range"
T0 = 1_650_000_000_000_000_000


def humble_ranges() -> list[object]:
    """The six Humble Range messages of :func:`humble_bag` (ranges 1.0, 1.125, ...)."""
    t = HUMBLE.types
    return [
        t[RANGE](
            header=t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="sonar"
            ),
            radiation_type=0,
            field_of_view=0.5,
            min_range=0.1,
            max_range=4.0,
            range=1.0 + i / 8,
        )
        for i in range(6)
    ]


def humble_bag(path: Path, ros_distro: str | None) -> Path:
    """A Humble-era .db3: no message_definitions table; ``ros_distro`` as given (None: no key)."""
    with Writer(path, version=8) as writer:
        sonar = writer.add_connection("/sonar", RANGE, typestore=HUMBLE)
        for i, msg in enumerate(humble_ranges()):
            writer.write(sonar, T0 + i * 10**8, bytes(HUMBLE.serialize_cdr(msg, RANGE)))
    (db3,) = path.glob("*.db3")
    db = sqlite3.connect(db3)
    db.execute("DROP TABLE message_definitions")
    db.commit()
    db.close()
    metadata = path / "metadata.yaml"
    text = re.sub(r"\n *ros_distro: .*", "", metadata.read_text())
    if ros_distro is not None:
        text += f"  ros_distro: {ros_distro}\n"
    metadata.write_text(text)
    return path
