"""Observe the running system over DDS: topic rates and fused altitude error against the truth.

What ``fusion check`` reports and the acceptance targets of the live system are measured with:
every sensor topic within 10 % of its nominal rate, odometry at the IMU rate, barometric altitude
at the pressure rate, and the fused altitude's RMS error below the GPS's own.
"""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

from bagkit.processes import Command, StopPolicy, Supervisor
from fusion import topics
from fusion.errors import FusionError
from fusion.nodes.shell import topic_qos
from fusion.processors.messages import stamp_ns

NOMINAL_HZ: dict[str, float] = {
    topics.IMU: 10.0,
    topics.GPS: 1.0,
    topics.TEMPERATURE: 2.0,
    topics.PRESSURE: 2.0,
    topics.ODOMETRY: 10.0,
    topics.BARO_ALTITUDE: 2.0,
}


@dataclass(frozen=True, slots=True)
class TopicRate:
    """Messages of one topic received in the observation window."""

    topic: str
    nominal_hz: float
    count: int
    rate_hz: float
    max_gap_s: float  # largest gap between consecutive header stamps

    def within(self, tolerance: float) -> bool:
        """Whether the rate is within ``tolerance`` (a fraction) of nominal."""
        return abs(self.rate_hz - self.nominal_hz) <= tolerance * self.nominal_hz


@dataclass(frozen=True, slots=True)
class LiveCheck:
    """What one observation of the live system measured."""

    duration_s: float
    rates: tuple[TopicRate, ...]
    fused_rms_m: float
    gps_rms_m: float
    altitude_samples: int
    alerts: tuple[str, ...] = field(default=())

    def targets_met(self, *, rate_tolerance: float = 0.1) -> bool:
        """Every rate within tolerance and the fused altitude better than GPS."""
        return all(r.within(rate_tolerance) for r in self.rates) and (
            self.fused_rms_m < self.gps_rms_m
        )

    def as_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "duration_s": self.duration_s,
            "rates": [
                {
                    "topic": r.topic,
                    "nominal_hz": r.nominal_hz,
                    "count": r.count,
                    "rate_hz": r.rate_hz,
                    "max_gap_s": r.max_gap_s,
                }
                for r in self.rates
            ],
            "fused_rms_m": self.fused_rms_m,
            "gps_rms_m": self.gps_rms_m,
            "altitude_samples": self.altitude_samples,
            "alerts": list(self.alerts),
            "targets_met": self.targets_met(),
        }


def observe(
    duration_s: float,
    *,
    startup_timeout_s: float = 20.0,
    is_alive: Callable[[], bool] = lambda: True,
) -> LiveCheck:
    """Subscribe to the system's topics and measure them for ``duration_s`` seconds.

    The window starts once every observed topic has delivered a message (discovery matches
    each publisher on its own), so start-up does not count against the rates.

    Raises:
        FusionError: a topic stayed silent for ``startup_timeout_s`` or ``is_alive`` went false.
    """
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("fusion_monitor", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    received: dict[str, list[tuple[float, Any]]] = {
        t: [] for t in (*NOMINAL_HZ, topics.GPS, topics.TRUTH, topics.ALERTS)
    }
    try:
        for topic, sink in received.items():
            node.create_subscription(
                topics.TOPIC_TYPES[topic], topic, _recorder(sink), topic_qos(topic)
            )

        def spin(until: Callable[[], bool], timeout_s: float) -> None:
            deadline = time.monotonic() + timeout_s
            while not until() and time.monotonic() < deadline:
                if not is_alive():
                    raise FusionError("the observed system stopped")
                executor.spin_once(timeout_sec=0.05)

        flowing = (*NOMINAL_HZ, topics.TRUTH)
        spin(lambda: all(received[t] for t in flowing), startup_timeout_s)
        silent = [t for t in flowing if not received[t]]
        if silent:
            raise FusionError(f"no messages on {', '.join(silent)} within {startup_timeout_s} s")
        start = time.monotonic()
        spin(lambda: time.monotonic() - start >= duration_s, duration_s + 1.0)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    return _measure(received, start, duration_s)


def check_system(
    duration_s: float, *, launch: bool = False, params_file: Path | None = None
) -> LiveCheck:
    """Measure the system for ``duration_s``; with ``launch``, start it first and stop it after.

    Raises:
        FusionError: the system did not come up or stopped during the measurement.
    """
    if not launch:
        return observe(duration_s)
    command = [sys.executable, "-m", "fusion", "launch"]
    if params_file is not None:
        command += ["--params", str(params_file)]
    quiet = subprocess.DEVNULL
    with Supervisor(StopPolicy(interrupt_s=15.0)) as group:
        system = group.start(Command("fusion launch", command, stdout=quiet, stderr=quiet))
        return observe(duration_s, is_alive=lambda: system.returncode is None)


def _measure(
    received: dict[str, list[tuple[float, Any]]], start: float, duration_s: float
) -> LiveCheck:
    rates = []
    for topic, hz in NOMINAL_HZ.items():
        window = [msg for t, msg in received[topic] if t >= start]
        stamps = [stamp_ns(msg.header.stamp) for msg in window]
        gaps = [(b - a) / 1e9 for a, b in itertools.pairwise(stamps)]
        rates.append(
            TopicRate(topic, hz, len(window), len(window) / duration_s, max(gaps, default=math.nan))
        )
    truth = {stamp_ns(m.header.stamp): m.pose.pose.position.z for _, m in received[topics.TRUTH]}

    def errors(topic: str, altitude: Callable[[Any], float]) -> list[float]:
        return [
            altitude(m) - truth[stamp_ns(m.header.stamp)]
            for t, m in received[topic]
            if t >= start and stamp_ns(m.header.stamp) in truth and math.isfinite(altitude(m))
        ]

    fused = errors(topics.ODOMETRY, lambda m: m.pose.pose.position.z)
    gps = errors(topics.GPS, lambda m: m.altitude)
    # Each /alerts message holds every sensor's state: keep each non-OK state once, in order.
    alerts = dict.fromkeys(
        f"{s.hardware_id}: {s.message}"
        for t, msg in received[topics.ALERTS]
        if t >= start
        for s in msg.status
        if s.level != DiagnosticStatus.OK
    )
    return LiveCheck(duration_s, tuple(rates), _rms(fused), _rms(gps), len(fused), tuple(alerts))


def _recorder(sink: list[tuple[float, Any]]) -> Callable[[Any], None]:
    def record(msg: Any) -> None:
        sink.append((time.monotonic(), msg))

    return record


def _rms(values: list[float]) -> float:
    return math.sqrt(math.fsum(v * v for v in values) / len(values)) if values else math.nan
