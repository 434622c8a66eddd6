"""The processes ``bench_record`` starts: the flood publisher and the subscribers it compares.

Run as ``python -m benchmarks.record_peers publish KIND SECONDS RATE_HZ`` or ``... subscribe
MODE KIND OUT``; a subscriber runs until SIGINT, then writes its counts, CPU and peak RSS as JSON
to OUT. The modes (see bench_record's docstring): ``count``, ``inline``, ``naive``, ``recorder``,
``snapshot`` (the recorder in snapshot mode, never triggered), ``health`` (the recorder with
the live health contract :data:`HEALTH_CONTRACT`, as ``bagkit record --health``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import signal
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

TOPIC = "/bench/record"
IMAGE_BYTES = 1 << 20
# The ``cloud`` kind: a PointCloud2 of x, y, z, intensity (float32) points, 4 MiB of them.
CLOUD_POINTS = 1 << 18
KINDS = ("imu", "image", "cloud")
READY_TIMEOUT_S = 30.0
# The ``snapshot`` mode's --max-cache-size: the Imu flood fills it in a few seconds.
SNAPSHOT_CACHE_BYTES = 64 << 20
# The ``health`` mode's contract: log-time checks and checks that read fields (the flood's
# values are zeros and its rate far above the bound: no check breaks).
HEALTH_CONTRACT = f"""\
topics:
  {TOPIC}:
    type: sensor_msgs/msg/Imu
    rate: {{min: 100, over: 1s}}
    max_gap: 1s
    values:
      linear_acceleration.z: {{min: -100, max: 100}}
    never: [isnan(angular_velocity)]
"""


def _message_type(kind: str) -> Any:
    if kind == "imu":
        from sensor_msgs.msg import Imu

        return Imu
    if kind == "cloud":
        from sensor_msgs.msg import PointCloud2

        return PointCloud2
    from sensor_msgs.msg import Image

    return Image


def _payload(kind: str) -> bytes:
    from rclpy.serialization import serialize_message

    message = _message_type(kind)()
    message.header.frame_id = "bench"
    if kind == "image":
        message.height, message.width, message.step = 512, 512, 2048
        message.encoding = "rgba8"
        message.data = bytes(IMAGE_BYTES)
    elif kind == "cloud":
        _fill_cloud(message)
    return bytes(serialize_message(message))


def _fill_cloud(message: Any) -> None:
    """A lidar-like scan: 64 rings of points at noisy ranges, with an intensity.

    Not zeros: float32 coordinates with noise in their low bits compress as a real scan's do
    (a little), so the writer's compression does the work it does on real clouds.
    """
    import numpy as np
    from sensor_msgs.msg import PointField

    rng = np.random.default_rng(7)
    azimuth = np.linspace(0, 2 * np.pi, CLOUD_POINTS // 64, endpoint=False)
    elevation = np.linspace(-0.4, 0.2, 64)
    az, el = np.meshgrid(azimuth, elevation)
    distance = 10 + 3 * np.sin(4 * az) + rng.normal(0, 0.02, az.shape)
    points = np.empty((64, len(azimuth), 4), np.float32)
    points[..., 0] = distance * np.cos(el) * np.cos(az)
    points[..., 1] = distance * np.cos(el) * np.sin(az)
    points[..., 2] = distance * np.sin(el)
    points[..., 3] = rng.uniform(0, 255, az.shape).round()
    message.height, message.width = 64, len(azimuth)
    message.fields = [
        PointField(name=name, offset=4 * index, datatype=PointField.FLOAT32, count=1)
        for index, name in enumerate(("x", "y", "z", "intensity"))
    ]
    message.point_step, message.row_step = 16, 16 * len(azimuth)
    message.is_dense = True
    message.data = points.tobytes()


def _init(name: str) -> tuple[Any, Any]:
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    return context, Node(name, context=context, start_parameter_services=False)


def publish(kind: str, seconds: float, rate_hz: float) -> None:
    """Flood (or pace at ``rate_hz``) TOPIC for ``seconds`` once matched; print the count."""
    from rclpy.duration import Duration
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    context, node = _init("bench_record_publisher")
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    publisher = node.create_publisher(_message_type(kind), TOPIC, qos)
    payload = _payload(kind)
    deadline = time.monotonic() + READY_TIMEOUT_S
    while publisher.get_subscription_count() == 0:
        if time.monotonic() > deadline:
            raise SystemExit("no subscriber matched")
        time.sleep(0.01)
    time.sleep(0.2)
    sent = 0
    start = time.monotonic()
    end = start + seconds
    period = 1.0 / rate_hz if rate_hz else 0.0
    publish_raw = publisher.publish
    blocked = 0
    while (now := time.monotonic()) < end:
        try:
            publish_raw(payload)
        except _rclpy.RCLError:
            # Keep-all history full for longer than the middleware's blocking time: this is
            # the flow control of a reliable keep-all flood; publish the same message again.
            blocked += 1
            continue
        sent += 1
        if period:
            delay = start + sent * period - now
            if delay > 0:
                time.sleep(delay)
    # Not acknowledged in time: the samples still in this publisher's history are never
    # delivered once it exits, and no subscriber can count them.
    acked = publisher.wait_for_all_acked(Duration(seconds=30))
    counts = {"sent": sent, "sent_bytes": sent * len(payload), "blocked": blocked, "acked": acked}
    print(json.dumps(counts), flush=True)
    node.destroy_node()
    context.try_shutdown()


def subscribe(mode: str, kind: str, out: Path, *, default_transport: bool = False) -> None:
    """Run one subscriber until SIGINT, then write its result as JSON to ``out``.

    ``default_transport``: without the large shared-memory queue of ``bagkit record``.
    """
    stop = {"now": False}

    def on_signal(_signum: int, _frame: object) -> None:
        stop["now"] = True

    signal.signal(signal.SIGINT, on_signal)
    from bagkit.native import keep_freed_memory
    from bagkit.ros.tuning import process_tuning

    # The recorder tunes its process itself (the library's process_tuning, as `bagkit record`);
    # the peers get the same tuning, so the ratios compare the work done per message, not the
    # allocator or the transport's queue. The default-transport runs vary the queue only.
    keep_freed_memory()
    ready = out.with_suffix(".ready")
    if mode in ("recorder", "snapshot", "health"):
        result = _run_recorder(
            out.with_suffix(".bag"),
            ready,
            stop,
            tune=not default_transport,
            snapshot_bytes=SNAPSHOT_CACHE_BYTES if mode == "snapshot" else 0,
            health=mode == "health",
        )
    else:
        with process_tuning(not default_transport):
            result = _run_subscriber(mode, kind, out.with_suffix(".bag"), ready, stop)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    result["peak_rss"] = _peak_rss()
    result["cpu_s"] = usage.ru_utime + usage.ru_stime
    out.write_text(json.dumps(result))


def _peak_rss() -> int:
    """Peak resident bytes of this process image.

    Not ``ru_maxrss``: it keeps the resident size of the parent that forked this process (the
    benchmark runner, 135 MiB after the other benchmarks), which hid every subscriber's own peak
    below it. VmHWM restarts at exec.
    """
    status = Path("/proc/self/status").read_text()
    return int(status.split("VmHWM:")[1].split()[0]) * 1024


def _thread_cpu() -> dict[str, float]:
    """CPU seconds of this process's live threads, by kind: the middleware's (``dds.*``),
    the recorder's (``bagkit-*``), the rest (``python``)."""
    tick = os.sysconf("SC_CLK_TCK")
    totals: dict[str, float] = {}
    for stat in Path("/proc/self/task").glob("*/stat"):
        with contextlib.suppress(OSError):
            text = stat.read_text()
            # comm is in parentheses and may hold spaces; utime and stime are fields 14 and 15.
            comm = text[text.index("(") + 1 : text.rindex(")")]
            fields = text[text.rindex(")") + 2 :].split()
            kind = "dds" if comm.startswith("dds.") else comm.removeprefix("bagkit-")
            totals[kind] = totals.get(kind, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return totals


def _run_recorder(
    bag: Path,
    ready: Path,
    stop: dict[str, bool],
    *,
    tune: bool,
    snapshot_bytes: int = 0,
    health: bool = False,
) -> dict[str, Any]:
    """``snapshot_bytes``: snapshot mode with this cache bound (0: a plain recording);
    ``health``: check HEALTH_CONTRACT live."""
    from bagkit.health import HealthSpec
    from bagkit.health.live import LiveHealth
    from bagkit.recording.options import RecordOptions, SnapshotOptions
    from bagkit.ros.record.recorder import Recorder

    options = RecordOptions(
        bag,
        topics=(TOPIC,),
        tune_process=tune,
        snapshot=SnapshotOptions(max_bytes=snapshot_bytes) if snapshot_bytes else None,
    )
    watch = LiveHealth(HealthSpec.parse(HEALTH_CONTRACT)) if health else None
    recorder = Recorder(options, health=watch)
    recorder.start()
    ready.touch()
    while not stop["now"]:
        time.sleep(0.05)
    threads = _thread_cpu()
    report = recorder.stop()
    topic = report.topic(TOPIC) if report.topics else None
    return {
        "messages": topic.messages if topic else 0,
        "bytes": topic.bytes if topic else 0,
        "span_ns": (topic.last_ns - topic.first_ns) if topic else 0,
        "lost": report.lost,
        "evicted": sum(report.evicted.values()),
        "health_breaks": sum(c.breaks for c in report.health or []),
        "error": report.error,
        "threads": threads,
    }


@dataclass
class _Counts:
    """What a subscriber received: messages, bytes, receive times of the first and last."""

    messages: int = 0
    bytes: int = 0
    first: int = 0
    last: int = 0

    def add(self, messages: int, nbytes: int, first: int, last: int) -> None:
        self.messages += messages
        self.bytes += nbytes
        self.first = self.first or first
        self.last = last

    def result(self, threads: dict[str, float]) -> dict[str, Any]:
        return {
            "messages": self.messages,
            "bytes": self.bytes,
            "span_ns": self.last - self.first,
            "lost": None,
            "error": None,
            "threads": threads,
        }


@dataclass
class _Subscriber:
    """One peer subscriber's node and where it reports."""

    mode: str
    context: Any
    node: Any
    message_type: Any
    qos: Any
    bag: Path
    ready: Path
    stop: dict[str, bool]
    counts: _Counts


def _run_subscriber(
    mode: str, kind: str, bag: Path, ready: Path, stop: dict[str, bool]
) -> dict[str, Any]:
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from bagkit.ros.qos import adapt_subscription_qos

    context, node = _init(f"bench_record_{mode}")
    # Exactly the profile the recorder subscribes with to a reliable publisher.
    qos = adapt_subscription_qos([QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)])
    peer = _Subscriber(mode, context, node, _message_type(kind), qos, bag, ready, stop, _Counts())
    if mode == "naive":
        _spin_callbacks(peer)
    else:
        _take_in_a_loop(peer)
    threads = _thread_cpu()
    node.destroy_node()
    context.try_shutdown()
    return peer.counts.result(threads)


def _bag_writer(peer: _Subscriber) -> Any:
    from bagkit.bag import BagWriter, TopicInfo
    from bagkit.ros.message_classes import message_type_name

    writer = BagWriter(peer.bag).open()
    writer.add_topic(TopicInfo(TOPIC, message_type_name(peer.message_type)))
    return writer


def _spin_callbacks(peer: _Subscriber) -> None:
    """``naive``: an executor callback per message writing a BagWriter."""
    from rclpy.executors import SingleThreadedExecutor

    writer = _bag_writer(peer)
    counts = peer.counts

    def on_message(data: bytes, info: Any) -> None:
        received = info["received_timestamp"]
        writer.write(TOPIC, data, log_time=received, publish_time=received)
        counts.add(1, len(data), received, received)

    peer.node.create_subscription(peer.message_type, TOPIC, on_message, peer.qos, raw=True)
    executor = SingleThreadedExecutor(context=peer.context)
    executor.add_node(peer.node)
    peer.ready.touch()
    while not peer.stop["now"]:
        executor.spin_once(timeout_sec=0.05)
    drained = -1
    while drained != counts.messages:
        drained = counts.messages
        executor.spin_once(timeout_sec=0.1)
    writer.close()


def _take_in_a_loop(peer: _Subscriber) -> None:
    """``count`` (take and count) or ``inline`` (bagkit's batched take written to a bag)."""
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    from bagkit.ros.record.take import take_serialized

    subscription = peer.node.create_subscription(
        peer.message_type, TOPIC, lambda _m: None, peer.qos, raw=True
    )
    handle = subscription.handle
    writer = _bag_writer(peer) if peer.mode == "inline" else None
    wait_set = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, peer.context.handle)
    counts = peer.counts
    peer.ready.touch()
    while True:
        stopping = peer.stop["now"]  # one more drain after the stop
        wait_set.clear_entities()
        wait_set.add_subscription(handle)
        wait_set.wait(0 if stopping else 50_000_000)
        if writer is None:
            while (taken := handle.take_message(peer.message_type, True)) is not None:
                received = taken[1]["received_timestamp"]
                counts.add(1, len(taken[0]), received, received)
        else:
            while batch := take_serialized(subscription, max_count=256, max_bytes=4 << 20):
                writer.write_batch(
                    TOPIC,
                    batch.payloads,
                    log_times=batch.received,
                    publish_times=batch.sources,
                    sequences=batch.sequences,
                )
                counts.add(len(batch), batch.nbytes, batch.received[0], batch.received[-1])
        if stopping:
            break
    if writer is not None:
        writer.close()


def _cli() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    roles = parser.add_subparsers(dest="role", required=True)
    pub = roles.add_parser("publish")
    pub.add_argument("kind", choices=KINDS)
    pub.add_argument("seconds", type=float)
    pub.add_argument("rate_hz", type=float)
    sub = roles.add_parser("subscribe")
    sub.add_argument("mode", choices=["count", "inline", "naive", "recorder", "snapshot", "health"])
    sub.add_argument("kind", choices=KINDS)
    sub.add_argument("out", type=Path)
    sub.add_argument("--default-transport", action="store_true")
    args = parser.parse_args()
    if args.role == "publish":
        publish(args.kind, args.seconds, args.rate_hz)
    else:
        subscribe(args.mode, args.kind, args.out, default_transport=args.default_transport)


if __name__ == "__main__":
    _cli()
