"""play and record answer a misspelt topic as the offline commands do: one ``error:`` line with
the closest name (the bag's for play, the graph's for record), exit 2."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from std_msgs.msg import String
from waiting import wait_for

from bagkit.bag import BagReader

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
BAG = Path(__file__).resolve().parents[2] / "fixtures" / "faults" / "golden"
pytestmark = pytest.mark.ros


def _error_line(result: subprocess.CompletedProcess[str]) -> str:
    assert result.returncode == 2, result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.stderr
    return errors[0]


def test_play_of_a_misspelt_topic_names_the_closest(tmp_path: Path) -> None:
    with BagReader(BAG) as reader:
        assert "/imu/data" in reader.topics
    result = subprocess.run(
        [BAGKIT, "play", str(BAG), "--topics", "/imu/dat"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    line = _error_line(result)
    assert line.startswith("error: topic /imu/dat not in the bag (did you mean /imu/data?")


def test_record_of_a_topic_that_never_appears_names_the_closest_on_the_graph(
    node: Any, processes: Any, tmp_path: Path
) -> None:
    publisher = node.create_publisher(String, "/trust/chatter", 10)
    bag = tmp_path / "bag"
    # --duration counts from the discovery of the named topics: this one waits for Ctrl-C.
    recorder = processes.start(
        ["bagkit", "record", "--topics", "/trust/chater", "-o", str(bag)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # Discovery is mutual: once this node sees the recorder, the recorder sees the publisher.
    wait_for(lambda: "bagkit_recorder" in node.get_node_names(), 30)
    time.sleep(1)
    recorder.send_signal(signal.SIGINT)
    stdout, stderr = recorder.communicate(timeout=30)
    line = _error_line(
        subprocess.CompletedProcess(recorder.args, recorder.returncode, stdout, stderr)
    )
    assert line.startswith("error: topic /trust/chater never appeared on the graph")
    assert "did you mean /trust/chatter?" in line
    assert BagReader(bag, allow_empty=True).open().message_count == 0
    node.destroy_publisher(publisher)
