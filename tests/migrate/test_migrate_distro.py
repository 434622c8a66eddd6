"""Bags that store no definitions (Foxy to Humble .db3) in ``migrate`` and ``doctor``: the
distribution's types, ``--distro`` when the bag names none, and no output whose stored
definitions its payloads do not follow. Values checked against rosbags' Humble types."""

from __future__ import annotations

from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process
from humble_bags import humble_bag, humble_ranges
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore


def _humble_bag(path: Path, ros_distro: str | None) -> list[float]:
    """:func:`humble_bag` at ``path``; returns the ranges written."""
    humble_bag(path, ros_distro)
    return [m.range for m in humble_ranges()]  # type: ignore[attr-defined]


@pytest.fixture(autouse=True)
def _no_distro_set(monkeypatch: pytest.MonkeyPatch) -> None:
    """``--distro`` is handed on in BAGKIT_DISTRO: none from the environment or a test before."""
    monkeypatch.delenv("BAGKIT_DISTRO", raising=False)


def test_a_bag_without_distro_is_refused_not_written_with_a_wrong_definition(
    tmp_path: Path,
) -> None:
    """Jazzy's Range is assumed and Humble's payloads do not follow it: before, the output
    stored Jazzy's Range over them (copied "as it is") and no reader decoded it."""
    _humble_bag(tmp_path / "old", None)
    done = bagkit_in_process(["migrate", tmp_path / "old", "-o", tmp_path / "new"])
    assert done.returncode == 2
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--distro" in errors[0] and "/sonar" in errors[0], done.stderr
    assert not (tmp_path / "new").exists()


def test_distro_names_what_the_bag_does_not(tmp_path: Path) -> None:
    ranges = _humble_bag(tmp_path / "old", None)
    done = bagkit_in_process(
        ["migrate", tmp_path / "old", "-o", tmp_path / "new", "--distro", "humble"]
    )
    assert done.returncode == 0, done.stderr
    assert "added: variance (float32)" in done.stdout
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([tmp_path / "new"], default_typestore=jazzy) as reader:
        read = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()]
    assert [(m.range, m.variance) for m in read] == [  # type: ignore[attr-defined]
        (pytest.approx(r), 0.0) for r in ranges
    ]


@pytest.mark.parametrize(
    ("ros_distro", "options"), [("humble", []), (None, ["--distro", "humble"])]
)
def test_doctor_decodes_with_the_bag_s_distribution(
    tmp_path: Path, ros_distro: str | None, options: list[str]
) -> None:
    """``doctor --deep`` decoded a textless .db3 with Jazzy's types whatever the bag named:
    every Humble Range "did not decode" (exit 1) while echo read them."""
    _humble_bag(tmp_path / "old", ros_distro)
    done = bagkit_in_process(["doctor", tmp_path / "old", "--deep", *options])
    assert done.returncode == 0, done.stdout + done.stderr
    assert "all decoded" in done.stdout
    drift = bagkit_in_process(["doctor", tmp_path / "old", "--against-installed", *options])
    assert drift.returncode == 1 and "added: variance (float32)" in drift.stdout, drift.stderr


def test_convert_refuses_a_wrong_guess_and_takes_distro(tmp_path: Path) -> None:
    """convert stored Jazzy's Range over the Humble payloads it guessed it for (exit 0, and
    doctor --deep then found every message undecodable); filter keeps the other topics."""
    ranges = _humble_bag(tmp_path / "old", None)
    done = bagkit_in_process(["convert", tmp_path / "old", "-o", tmp_path / "guessed"])
    assert done.returncode == 2 and not (tmp_path / "guessed").exists()
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--distro" in errors[0], done.stderr
    done = bagkit_in_process(
        ["convert", tmp_path / "old", "-o", tmp_path / "new", "-s", "sqlite3", "--distro", "humble"]
    )
    assert done.returncode == 0, done.stderr
    with AnyReader([tmp_path / "new"]) as reader:  # the definitions stored in it
        read = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()]
    assert [m.range for m in read] == [pytest.approx(r) for r in ranges]  # type: ignore[attr-defined]
    assert not hasattr(read[0], "variance")
