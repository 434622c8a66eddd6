"""Replay start: command start to the first message at a subscriber already on the graph.

A subscriber process stays on the graph; each run starts, in turn, ``bagkit play BAG`` (one
String message on ``/start``) and a minimal rclpy script that publishes the same message as soon
as one subscription matched (the peer: what any publisher needs to be heard). Both start as
processes on the same machine in the same minute; the time from ``Popen`` to the subscriber's
reception is taken for each, RUNS times, interleaved. Target (issue 36, item 1): bagkit's
median within max(1 s, the script's median + 0.5 s). Discovery decides much of either time: a
participant already on the graph is often found only at its periodic announcement (every 3 s
with Fast DDS), so single runs vary by seconds: read medians.

Run: ``.venv/bin/python -m benchmarks replay_start``
"""

from __future__ import annotations

import os
import select
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_startup import cached_bytecode_env

RUNS = 7
TOPIC = "/start"
MARGIN_S = 0.5
FLOOR_S = 1.0

_LISTENER = """
import sys, time, rclpy
from rclpy.executors import ExternalShutdownException
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("replay_start_listener")
node.create_subscription(
    String, "/start", lambda m: print(time.time(), m.data, flush=True), 10
)
print("ready", flush=True)
try:
    rclpy.spin(node)
except ExternalShutdownException:  # terminate() at the end
    pass
"""

# The peer: the fewest lines that publish once without losing the message.
_SCRIPT = """
import time, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("replay_start_script")
publisher = node.create_publisher(String, "/start", 10)
while publisher.get_subscription_count() == 0:
    time.sleep(0.005)
publisher.publish(String(data="script"))
publisher.wait_for_all_acked()
"""


def _write_bag(path: Path) -> None:
    from rclpy.qos import QoSProfile
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    from bagkit.bag import BagWriter, TopicInfo
    from bagkit.ros.qos import dump_offered_qos_profiles

    offered = dump_offered_qos_profiles([QoSProfile(depth=10)])
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo(TOPIC, "std_msgs/msg/String", offered_qos_profiles=offered))
        writer.write(TOPIC, serialize_message(String(data="bag")), log_time=1_700_000_000 * 10**9)


def _first_message(
    listener: subprocess.Popen[str], command: list[str], data: str
) -> tuple[float, str]:
    """Seconds from starting ``command`` to the listener's reception of ``data``, and what the
    command printed on stderr."""
    assert listener.stdout is not None
    start = time.time()
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=cached_bytecode_env()
    )
    ready, _, _ = select.select([listener.stdout], [], [], 30.0)
    if not ready:
        process.kill()
        raise RuntimeError(f"no message from {command[0]} within 30 s")
    received, got = listener.stdout.readline().split()
    if got != data:
        raise RuntimeError(f"expected {data!r} from {command[0]}, the listener got {got!r}")
    _, err = process.communicate(timeout=30)
    return float(received) - start, err.decode(errors="replace").strip()


def main() -> bool:
    """Print the medians and bagkit's difference to the script; True when the target is met."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "start"
        _write_bag(bag)
        script = Path(tmp) / "script.py"
        script.write_text(_SCRIPT)
        commands = {
            "script": ([sys.executable, str(script)], "script"),
            "bagkit play": ([bagkit, "play", str(bag)], "bag"),
        }
        listener = subprocess.Popen(
            [sys.executable, "-c", _LISTENER], stdout=subprocess.PIPE, text=True
        )
        try:
            assert listener.stdout is not None
            assert listener.stdout.readline().strip() == "ready"
            times: dict[str, list[float]] = {name: [] for name in commands}
            for run in range(RUNS):
                for name, (command, data) in commands.items():
                    seconds, err = _first_message(listener, command, data)
                    times[name].append(seconds)
                    waited = f" ({err.splitlines()[0]})" if name != "script" and err else ""
                    print(f"  run {run + 1} {name:12s} {seconds:6.3f} s{waited}", flush=True)
        finally:
            listener.terminate()
            try:
                listener.wait(timeout=5)
            except subprocess.TimeoutExpired:  # its DDS teardown sometimes hangs
                listener.kill()
                listener.wait()
    script_s = statistics.median(times["script"])
    bagkit_s = statistics.median(times["bagkit play"])
    target = max(FLOOR_S, script_s + MARGIN_S)
    met = bagkit_s <= target
    print(
        f"medians of {RUNS}: script {script_s:.3f} s, bagkit play {bagkit_s:.3f} s "
        f"(+{bagkit_s - script_s:.3f} s, {bagkit_s / script_s:.2f}x); target <= {target:.3f} s: "
        + ("met" if met else "MISSED")
    )
    return met


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
