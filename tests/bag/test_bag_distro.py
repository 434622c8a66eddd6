"""Bags without stored definitions (Foxy to Humble .db3): their distribution's types, then
Jazzy's with one warning; ``--distro`` overrides. Values checked against rosbags' Humble types."""

from __future__ import annotations

import json
import pickle
import sqlite3
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess
from humble_bags import HUMBLE, RANGE, T0, humble_bag, humble_ranges
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader
from bagkit.bag.distro_definitions import DistroDefinitionsWarning

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _echo(bag: Path, *options: str) -> subprocess.CompletedProcess[str]:
    """``bagkit echo`` of /sonar in this process (tests/bagkit_runs.py); stats is a real one."""
    return bagkit_in_process(["echo", bag, "/sonar", "--format", "json", *options])


def _ranges_echoed(stdout: str) -> list[float]:
    return [json.loads(line)["data"]["range"] for line in stdout.splitlines()]


def test_the_bag_distro_types_decode_it(tmp_path: Path) -> None:
    bag = humble_bag(tmp_path / "humble", "humble")
    proc = _echo(bag)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert _ranges_echoed(proc.stdout) == [m.range for m in humble_ranges()]  # type: ignore[attr-defined]
    assert "variance" not in json.loads(proc.stdout.splitlines()[0])["data"]
    with BagReader(bag) as reader:
        assert reader.definitions[RANGE] == HUMBLE.generate_msgdef(RANGE, ros_version=2)[0]


def test_without_ros_distro_jazzy_is_used_with_one_warning(tmp_path: Path) -> None:
    bag = humble_bag(tmp_path / "unnamed", None)
    proc = _echo(bag)
    # Jazzy's Range has a variance the Humble payloads lack: nothing decodes.
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 2, proc.stderr
    assert lines[0].startswith("warning:") and "Jazzy" in lines[0] and RANGE in lines[0]
    assert lines[0].endswith("(--distro NAME chooses)")
    assert lines[1].startswith("error:") and "none of the 6 messages" in lines[1]


def test_the_library_warning_names_the_environment_setting(tmp_path: Path) -> None:
    bag = humble_bag(tmp_path / "unnamed", None)
    with BagReader(bag) as reader, pytest.warns(DistroDefinitionsWarning) as caught:
        assert RANGE in reader.definitions
    (warning,) = caught
    assert str(warning.message).endswith("with ROS 2 Jazzy's (BAGKIT_DISTRO chooses)")
    assert "--distro" not in str(warning.message)
    # As another process gets it (pytest-xdist, a Dask worker): the same warning.
    again = pickle.loads(pickle.dumps(warning.message))
    assert type(again) is DistroDefinitionsWarning and str(again) == str(warning.message)


@pytest.mark.parametrize("ros_distro", [None, "jazzy"])
def test_distro_option_overrides(tmp_path: Path, ros_distro: str | None) -> None:
    bag = humble_bag(tmp_path / "bag", ros_distro)
    proc = _echo(bag, "--distro", "humble")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert _ranges_echoed(proc.stdout) == [m.range for m in humble_ranges()]  # type: ignore[attr-defined]
    stats = subprocess.run(
        [BAGKIT, "stats", "summary", str(bag), "--distro", "humble", "--format", "json"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert stats.returncode == 0 and stats.stderr == "", stats.stderr
    fields = {f["field"]: f for f in json.loads(stats.stdout)["topics"][0]["fields"]}
    assert fields["range"]["max"] == max(m.range for m in humble_ranges())  # type: ignore[attr-defined]


def test_compare_takes_the_distro_option(tmp_path: Path) -> None:
    # compare decodes both bags as every reading command does: --distro is its choice too.
    bag = humble_bag(tmp_path / "bag", None)
    # Jazzy's Range does not decode the Humble payloads: compared byte for byte, said so.
    assert "compared byte for byte" in bagkit_in_process(["compare", bag, bag]).stderr
    proc = bagkit_in_process(["compare", bag, bag, "--distro", "humble"])
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


def test_an_unknown_distro_is_a_usage_error(tmp_path: Path) -> None:
    proc = _echo(humble_bag(tmp_path / "bag", "humble"), "--distro", "ardent")
    assert proc.returncode == 2 and "ardent" in proc.stderr and "Traceback" not in proc.stderr


def test_a_stored_empty_definition_is_a_definition(tmp_path: Path) -> None:
    # std_msgs/msg/Empty's text is empty: rosbag2 and rosbags store it so (encoding ros2msg),
    # a stored definition, not a missing one.
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    with Writer(tmp_path / "bag", version=9) as writer:
        tick = writer.add_connection("/tick", "std_msgs/msg/Empty", typestore=jazzy)
        empty = jazzy.serialize_cdr(jazzy.types["std_msgs/msg/Empty"](), "std_msgs/msg/Empty")
        for i in range(3):
            writer.write(tick, T0 + i, bytes(empty))
    (db3,) = (tmp_path / "bag").glob("*.db3")
    with sqlite3.connect(db3) as db:
        rows = db.execute("SELECT encoding, encoded_message_definition FROM message_definitions")
        assert rows.fetchall() == [("ros2msg", "")]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DistroDefinitionsWarning)
        with BagReader(tmp_path / "bag") as bag:
            assert bag.definitions == {"std_msgs/msg/Empty": ""}
    echo = bagkit_subprocess(["echo", "bag", "/tick", "--format", "json"], tmp_path)
    assert echo.returncode == 0, echo.stderr
    assert echo.stderr == ""
    assert [json.loads(line)["data"] for line in echo.stdout.splitlines()] == [{}] * 3
