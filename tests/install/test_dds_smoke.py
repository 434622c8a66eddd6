"""record -> replay -> echo over DDS: what CI runs on each extra Python besides the offline suite.

``bagkit replay`` publishes two topics of a golden bag while ``bagkit record`` records them;
``bagkit echo`` of the recording then shows the golden's messages, field for field.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

GOLDEN = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"
TOPICS = ["/gps/fix", "/imu/data"]


def bagkit(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(Path(sys.executable).with_name("bagkit")), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def messages(bag: Path, topic: str) -> list[Any]:
    """The decoded messages of ``topic``, as ``bagkit echo --format json`` prints them."""
    echoed = bagkit("echo", bag, topic, "--format", "json")
    assert echoed.returncode == 0, echoed.stderr
    return [json.loads(line)["data"] for line in echoed.stdout.splitlines()]


def test_record_replay_echo(processes: Any, tmp_path: Path) -> None:
    recording = tmp_path / "recording"
    recorder = processes.start(
        ["bagkit", "record", "-o", str(recording), *TOPICS],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    waits = [arg for topic in TOPICS for arg in ("--wait-for", topic)]
    replayed = bagkit("replay", GOLDEN, "--rate", "8", "--topics", *TOPICS, *waits)
    assert replayed.returncode == 0, replayed.stderr
    recorder.send_signal(signal.SIGINT)
    _, errors = recorder.communicate(timeout=30)
    # Stopped by Ctrl-C: 128 + SIGINT, as a shell reports it, once the bag is finished.
    assert recorder.returncode == 128 + signal.SIGINT, errors.decode()
    for topic in TOPICS:
        assert messages(recording, topic) == messages(GOLDEN, topic), topic
