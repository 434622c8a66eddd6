"""Lockstep replay speed on the golden fixtures, against real time (the live replay's speed).

For each fixture: the bag time covered per second of wall time by ``run_lockstep`` (best of 3,
target >= 100x real time, i.e. a live ``bagkit replay`` of the same bag takes 100 times longer),
and the share of that wall time spent inside the processors themselves (the rest is the
harness: reading, rclpy (de)serialization, re-encoding, writing).

Run: ``.venv/bin/python -m benchmarks lockstep``
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.regression.lockstep import LockstepResult, run_lockstep
from bagkit.regression.processor import Processor, make_processors
from bagkit.regression.spec import FixtureSpec, find_fixtures

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
TARGET_SPEEDUP = 100.0
RUNS = 3


def _processors(spec: FixtureSpec) -> list[Processor]:
    assert spec.processor is not None
    return make_processors(spec.processor, spec.processor_args)


def _best_run(spec: FixtureSpec, workdir: Path) -> LockstepResult:
    best: LockstepResult | None = None
    for run in range(RUNS):
        result = run_lockstep(
            spec.bag,
            workdir / f"{spec.name}-{run}",
            processors=_processors(spec),
            input_topics=spec.inputs,
            output_topics=spec.outputs,
        )
        if best is None or result.wall_time_s < best.wall_time_s:
            best = result
    assert best is not None
    return best


def _processor_seconds(spec: FixtureSpec) -> float:
    """Wall time of the processors alone on the fixture's inputs (deserialized beforehand)."""
    from rclpy.serialization import deserialize_message

    from bagkit.ros.message_classes import import_message_type

    with BagReader(spec.bag) as reader:
        classes = {t: import_message_type(reader.topics[t].type) for t in spec.inputs}
        inputs = [
            (m.topic, deserialize_message(m.data, classes[m.topic]), m.log_time)
            for m in reader.messages(topics=list(spec.inputs))
        ]
    processors = _processors(spec)
    periods = {id(p): p.timer_period_ns for p in processors}
    next_tick = {id(p): inputs[0][2] for p in processors}
    start = time.perf_counter()
    for topic, msg, now in inputs:
        for processor in processors:
            period = periods[id(processor)]
            if period and next_tick[id(processor)] <= now:
                processor.on_timer(now)
                next_tick[id(processor)] = (now // period + 1) * period
            if topic in processor.input_topics:
                processor.on_message(topic, msg, now)
    return time.perf_counter() - start


def main() -> bool:
    """Print each fixture's speed against real time; True when all reach the target."""
    specs = find_fixtures(FIXTURES)
    if not specs:
        print(f"no fixtures under {FIXTURES}")
        return False
    ok = True
    header = f"{'fixture':<10}{'bag s':>8}{'inputs':>8}{'outputs':>9}{'wall s':>9}"
    print(f"{header}{'x real time':>13}{'in processors':>15}")
    with tempfile.TemporaryDirectory() as tmp:
        for spec in specs:
            result = _best_run(spec, Path(tmp))
            in_processors = min(_processor_seconds(spec) for _ in range(RUNS))
            outputs = sum(result.output_counts.values())
            met = result.speedup >= TARGET_SPEEDUP
            ok &= met
            print(
                f"{spec.name:<10}{result.bag_duration_ns / 1e9:>8.1f}{result.input_messages:>8}"
                f"{outputs:>9}{result.wall_time_s:>9.3f}{result.speedup:>12.0f}x"
                f"{in_processors / result.wall_time_s:>14.0%}"
                f"{'' if met else f'  (target {TARGET_SPEEDUP:.0f}x missed)'}"
            )
    print(
        "x real time: bag time / wall time of run_lockstep (a live replay runs at 1x); "
        "in processors: share of the wall time spent in the fusion processors' own code"
    )
    return ok
