"""The live fusion system: rates and altitude accuracy over DDS, and lockstep throughput.

Figures are ratios against a reference measured in the same run: each topic's measured rate
against its nominal rate, the fused altitude's RMS error against the GPS altitude's RMS error
(both against the simulated truth), and lockstep simulation speed against real time.
"""

from __future__ import annotations

import time

from fusion.nodes.monitor import check_system
from fusion.simulate import simulate

LIVE_SECONDS = 30.0
LOCKSTEP_SECONDS = 600.0
LOCKSTEP_TARGET = 50.0  # times real time


def main() -> bool:
    """Run both measurements; True when every target is met."""
    begin = time.perf_counter()
    count = sum(1 for _ in simulate(LOCKSTEP_SECONDS))
    elapsed = time.perf_counter() - begin
    speed = LOCKSTEP_SECONDS / elapsed
    print(
        f"lockstep: {LOCKSTEP_SECONDS:g} s of flight, {count} messages in {elapsed:.2f} s: "
        f"{speed:.0f}x real time (target >= {LOCKSTEP_TARGET:g}x)"
    )

    check = check_system(LIVE_SECONDS, launch=True)
    print(f"live: fusion launch observed for {LIVE_SECONDS:g} s over DDS")
    for rate in check.rates:
        print(
            f"  {rate.topic:<24} {rate.count:>4} msgs  {rate.rate_hz:6.2f} Hz  "
            f"measured/nominal {rate.rate_hz / rate.nominal_hz:.3f}  max gap {rate.max_gap_s:.3f} s"
        )
    print(
        f"  altitude RMS error: fused {check.fused_rms_m:.2f} m, GPS {check.gps_rms_m:.2f} m, "
        f"fused/GPS {check.fused_rms_m / check.gps_rms_m:.2f} (target < 1)"
    )
    return check.targets_met(rate_tolerance=0.1) and speed >= LOCKSTEP_TARGET
