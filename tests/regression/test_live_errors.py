"""A live run whose system dies says which process and why (the tail of its log)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
import yaml
from doubler_fixture import write_core, write_fixture

from bagkit.regression.errors import LiveRunError, SpecError
from bagkit.regression.live import check_live, record_golden
from bagkit.regression.spec import load_spec

DYING = (
    "import sys; print('starting the doubler'); "
    "print('fatal: no parameter file at /etc/doubler.yaml', flush=True); sys.exit(3)"
)


def with_commands(fixture: Path, **commands: object) -> Path:
    spec_file = fixture / "spec.yaml"
    spec = yaml.safe_load(spec_file.read_text())
    spec.update(commands)
    spec_file.write_text(yaml.safe_dump(spec))
    return fixture


@pytest.mark.ros
def test_a_node_that_exits_early_is_named_with_its_log(tmp_path: Path) -> None:
    fixture = with_commands(write_fixture(tmp_path / "ramp"), launch=[["python", "-c", DYING]])
    with pytest.raises(LiveRunError) as caught:
        check_live(load_spec(fixture), tmp_path / "work", startup_timeout=60)
    message = str(caught.value)
    assert message.startswith("a process of the live run exited early: launch (exit code 3)")
    assert "starting the doubler\nfatal: no parameter file at /etc/doubler.yaml" in message
    assert caught.value.exit_code == 1


@pytest.mark.ros
def test_a_recording_whose_system_dies_says_which_and_why(tmp_path: Path) -> None:
    fixture = with_commands(
        write_fixture(tmp_path / "ramp"),
        record_launch=[
            [sys.executable, "-c", "import time; time.sleep(60)"],
            ["python", "-c", DYING],
        ],
    )
    with pytest.raises(LiveRunError, match=r"(?s)system-1 \(exit code 3\)[^\n]*\n.*fatal: no par"):
        record_golden(load_spec(fixture), tmp_path / "work", log=lambda _: None)


def test_a_command_that_cannot_start_is_a_clean_error(tmp_path: Path) -> None:
    fixture = with_commands(write_fixture(tmp_path / "ramp"), record_launch="/nonexistent/node")
    with pytest.raises(LiveRunError, match="cannot start system"):
        record_golden(load_spec(fixture), tmp_path / "work", log=lambda _: None)


def test_modes_need_their_system(tmp_path: Path) -> None:
    fixture = write_fixture(tmp_path / "ramp")
    with pytest.raises(SpecError, match="live mode needs a launch command"):
        check_live(load_spec(fixture), tmp_path / "work")
    with_commands(fixture, modes=["live"])
    with pytest.raises(SpecError, match="mode live needs launch"):
        load_spec(fixture)


# Once the recorder subscribes, publishes /value at 10 Hz for one second, then stays up silent.
FALLS_SILENT = (
    "import time, rclpy; from std_msgs.msg import Float64; rclpy.init(); "
    "node = rclpy.create_node('falls_silent'); pub = node.create_publisher(Float64, '/value', 10)\n"
    "while not pub.get_subscription_count(): time.sleep(0.05)\n"
    "for i in range(10): pub.publish(Float64(data=float(i))); time.sleep(0.1)\n"
    "time.sleep(60)"
)


@pytest.mark.ros
def test_a_golden_shorter_than_asked_says_which_topic_ended_early(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write_core(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    fixture = write_fixture(tmp_path / "ramp")
    spec = yaml.safe_load((fixture / "spec.yaml").read_text())
    spec.update(duration=3, record_launch=[[sys.executable, "-c", FALLS_SILENT]])
    (fixture / "spec.yaml").write_text(yaml.safe_dump(spec))
    said: list[str] = []
    counts = record_golden(load_spec(fixture), tmp_path / "work", log=said.append)
    assert counts["/value"] == 10
    short = [line for line in said if "asked" in line]
    assert len(short) == 1, said
    # The ten messages span 0.9 s (a loaded machine may stretch it), not the 3 s asked.
    match = re.search(
        r"spans ([\d.]+) s of the 3 s asked "
        r"\(/doubled 0\.00-[\d.]+ s, /sum [^,]+, /value 0\.00-([\d.]+) s\)",
        short[0],
    )
    assert match is not None, short[0]
    assert match.group(1) == f"{float(match.group(2)):.1f}" and 0.8 < float(match.group(2)) < 3
