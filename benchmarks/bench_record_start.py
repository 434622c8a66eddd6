"""Record start: a publisher appearing to its first message taken by ``bagkit record``.

``bagkit record /start`` stays on the graph, then, RUNS times, a publisher process starts,
publishes one String on ``/start`` as soon as one subscription matched, and waits for the
acknowledgement; the time from its node's creation (the participant appearing) to the
acknowledgement is taken. The same with a plain rclpy subscriber in place of the recorder (the
peer: what any subscriber gets). Target (issue 36, item 1): bagkit's median within 1 s. A
new participant often loses the first answer of the ones already on the graph (Fast DDS 2.14
announces before it listens) and finds them at their next announcement: every 3 s by default,
0.5 s for bagkit's participants (``bagkit.ros.fastdds.ANNOUNCEMENT_PERIOD_NS``).

Run: ``.venv/bin/python -m benchmarks record_start``
"""

from __future__ import annotations

import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_replay_start import _LISTENER
from benchmarks.bench_startup import cached_bytecode_env

RUNS = 9
TARGET_S = 1.0
# Seconds the subscriber or the recorder gets to be on the graph before the first publisher.
SETTLE_S = 4.0

_PUBLISHER = """
import time, rclpy
from rclpy.duration import Duration
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("record_start_publisher")
appeared = time.monotonic()
publisher = node.create_publisher(String, "/start", 10)
while publisher.get_subscription_count() == 0:
    time.sleep(0.005)
publisher.publish(String(data="start"))
if not publisher.wait_for_all_acked(Duration(seconds=20)):
    raise SystemExit("not acknowledged")
print(time.monotonic() - appeared)
"""


def _first_takes(command: list[str]) -> list[float]:
    """Seconds from each publisher's node to its message's acknowledgement by ``command``."""
    taker = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=cached_bytecode_env()
    )
    try:
        time.sleep(SETTLE_S)
        return [
            float(
                subprocess.run(
                    [sys.executable, "-c", _PUBLISHER],
                    capture_output=True,
                    text=True,
                    check=True,
                    timeout=60,
                    env=cached_bytecode_env(),
                ).stdout
            )
            for _ in range(RUNS)
        ]
    finally:
        taker.send_signal(signal.SIGINT)
        try:
            taker.wait(timeout=10)
        except subprocess.TimeoutExpired:  # a DDS teardown that hangs
            taker.kill()
            taker.wait()


def main() -> bool:
    """Print the medians; True when bagkit's is within the target."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    with tempfile.TemporaryDirectory() as tmp:
        takers = {
            "subscriber": [sys.executable, "-c", _LISTENER],
            "bagkit record": [bagkit, "record", "-o", str(Path(tmp) / "bag"), "/start"],
        }
        medians, worst = {}, {}
        for name, command in takers.items():
            times = _first_takes(command)
            medians[name], worst[name] = statistics.median(times), max(times)
            runs = ", ".join(f"{t:.2f}" for t in times)
            print(f"  {name:14s} median {medians[name]:.3f} s (runs: {runs})", flush=True)
    met = medians["bagkit record"] <= TARGET_S
    print(
        f"medians of {RUNS}: subscriber {medians['subscriber']:.3f} s (worst "
        f"{worst['subscriber']:.2f}), bagkit record {medians['bagkit record']:.3f} s (worst "
        f"{worst['bagkit record']:.2f}); target <= {TARGET_S:.1f} s: "
        + ("met" if met else "MISSED")
    )
    return met


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
