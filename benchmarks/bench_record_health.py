"""``bagkit record --health`` under the Imu flood: the live contract must not slow recording.

The flood of ``bench_record`` (its own publisher process, reliable keep-all) to ``count`` (a
wait-set loop that only counts: the ceiling), the plain ``recorder`` and ``health`` (the
recorder checking ``record_peers.HEALTH_CONTRACT`` live: rate and gap from the log times, a
value bound and an ``isnan`` that decode every message), interleaved, best of three. Target:
``health`` records >= 0.9 of ``count``'s rate with 0 lost and every message in the bag; the
ratio to the plain recorder is printed.

Run: ``.venv/bin/python -m benchmarks record_health``
"""

from __future__ import annotations

from benchmarks.bench_record import IMU_SECONDS, RATE_FLOOR, _best_of, _line

ROUNDS = 3


def main() -> bool:
    """Print the runs and the ratios; return whether the target holds."""
    print(f"Imu flood, reliable keep-all, {IMU_SECONDS:g} s per run, best of {ROUNDS}:")
    runs = _best_of(("count", "recorder", "health"), "imu", IMU_SECONDS, ROUNDS)
    for mode, result in runs.items():
        print(_line(mode, result))
    health, count, plain = runs["health"], runs["count"], runs["recorder"]
    ratio = health["rate"] / count["rate"]
    complete = health["lost"] == 0 and health["in_bag"] == health["sent"]
    print(
        f"  health/count rate {ratio:.2f} (target >= {RATE_FLOOR}); health/recorder rate "
        f"{health['rate'] / plain['rate']:.2f}; lost {health['lost']}, in the bag "
        f"{health['in_bag']}/{health['sent']}; checks broken {health['health_breaks']}"
    )
    return ratio >= RATE_FLOOR and complete
