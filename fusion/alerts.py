"""Alert rules: value ranges with hysteresis, debouncing, stuck sensors, staleness, GPS fix.

Pure: the caller passes sample values and the time in ns; the monitor says which sensors changed
state. Levels match ``diagnostic_msgs/DiagnosticStatus`` (OK, WARN, ERROR, STALE).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field


class Level(enum.IntEnum):
    """Severity, ordered like DiagnosticStatus levels."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True, slots=True)
class RangeRule:
    """Valid ranges of one field.

    Outside ``warn`` is WARN, outside ``error`` is ERROR. Once a level is reached, the value must
    come back inside that level's range by ``hysteresis`` before the level drops, so a value
    hovering at a limit does not flap.
    """

    name: str
    warn: tuple[float, float]
    error: tuple[float, float]
    hysteresis: float = 0.0

    def level(self, value: float, current: Level) -> Level:
        """The level of ``value`` given the rule's ``current`` level (NaN is an ERROR)."""
        if math.isnan(value):
            return Level.ERROR
        for level, (low, high) in ((Level.ERROR, self.error), (Level.WARN, self.warn)):
            margin = self.hysteresis if current >= level else 0.0
            if value < low + margin or value > high - margin:
                return level
        return Level.OK


@dataclass(frozen=True, slots=True)
class SensorRules:
    """Everything checked for one sensor."""

    name: str
    period_ns: int
    ranges: tuple[RangeRule, ...] = ()
    stuck_samples: int = 0  # 0: no stuck detection
    requires_fix: bool = False


@dataclass(frozen=True, slots=True)
class SensorState:
    """The published state of one sensor: its level and why."""

    name: str
    level: Level
    reasons: tuple[str, ...]
    values: tuple[tuple[str, float], ...]

    @property
    def message(self) -> str:
        """One line for humans."""
        return "; ".join(self.reasons) if self.reasons else "ok"


@dataclass(slots=True)
class _SensorMonitor:
    rules: SensorRules
    debounce_samples: int
    rule_levels: dict[str, Level] = field(default_factory=dict)
    last_seen_ns: int | None = None
    last_stuck_key: tuple[float, ...] | None = None
    repeats: int = 0
    candidate: tuple[Level, tuple[str, ...]] | None = None
    candidate_count: int = 0
    values: tuple[tuple[str, float], ...] = ()


class AlertMonitor:
    """Tracks every sensor's state from its samples and the clock."""

    def __init__(
        self,
        sensors: Mapping[str, SensorRules],
        *,
        stale_periods: float = 3.0,
        debounce_samples: int = 2,
        startup_grace_ns: int = 0,
    ) -> None:
        self.stale_periods = stale_periods
        self.startup_grace_ns = startup_grace_ns
        self._monitors = {
            name: _SensorMonitor(rules, max(1, debounce_samples)) for name, rules in sensors.items()
        }
        self._start_ns: int | None = None
        self._published: dict[str, SensorState] = {}

    @property
    def states(self) -> dict[str, SensorState]:
        """The current state of every sensor, in configuration order."""
        return dict(self._published)

    def on_sample(
        self,
        sensor: str,
        now_ns: int,
        values: Mapping[str, float],
        *,
        stuck_key: tuple[float, ...] = (),
        has_fix: bool = True,
    ) -> list[SensorState]:
        """Feed one sample; returns the sensors whose state changed (at most this one).

        ``values`` are the fields the range rules name; ``stuck_key`` is what must change from
        sample to sample for a live sensor (all raw readings).
        """
        self._start(now_ns)
        mon = self._monitors[sensor]
        mon.last_seen_ns = now_ns
        rules = mon.rules
        level = Level.OK
        reasons: list[str] = []
        for rule in rules.ranges:
            value = values[rule.name]
            rule_level = rule.level(value, mon.rule_levels.get(rule.name, Level.OK))
            mon.rule_levels[rule.name] = rule_level
            if rule_level > Level.OK:
                low, high = rule.error if rule_level is Level.ERROR else rule.warn
                reasons.append(f"{rule.name} {value:.6g} outside [{low:g}, {high:g}]")
                level = max(level, rule_level)
        if rules.stuck_samples > 0:
            mon.repeats = mon.repeats + 1 if stuck_key == mon.last_stuck_key else 0
            mon.last_stuck_key = stuck_key
            if mon.repeats + 1 >= rules.stuck_samples:
                reasons.append(f"stuck: {mon.repeats + 1} identical samples")
                level = Level.ERROR
        if rules.requires_fix and not has_fix:
            reasons.append("no GPS fix")
            level = Level.ERROR
        mon.values = tuple(values.items())
        return self._debounce(mon, level, tuple(reasons))

    def check(self, now_ns: int) -> list[SensorState]:
        """Check staleness at ``now_ns``; returns the sensors whose state changed."""
        self._start(now_ns)
        assert self._start_ns is not None
        changed = []
        for name, mon in self._monitors.items():
            limit_ns = self.stale_periods * mon.rules.period_ns
            if mon.last_seen_ns is None:
                # Peers take a moment to be discovered: a sensor never heard from gets longer.
                last = self._start_ns
                limit_ns = max(limit_ns, self.startup_grace_ns)
            else:
                last = mon.last_seen_ns
            silent_ns = now_ns - last
            if silent_ns > limit_ns:
                reason = (
                    f"no message for {silent_ns / 1e9:.1f} s"
                    if mon.last_seen_ns is not None
                    else "no message received yet"
                )
                changed += self._publish(name, Level.STALE, (reason,), mon.values)
        return changed

    def _start(self, now_ns: int) -> None:
        if self._start_ns is None:
            self._start_ns = now_ns
            for name, mon in self._monitors.items():
                self._published[name] = SensorState(name, Level.OK, (), mon.values)

    def _debounce(
        self, mon: _SensorMonitor, level: Level, reasons: tuple[str, ...]
    ) -> list[SensorState]:
        name = mon.rules.name
        current = self._published[name]
        # A reading after silence ends STALE at once: a fresh sample is the evidence.
        if current.level is Level.STALE:
            mon.candidate = None
            return self._publish(name, level, reasons, mon.values)
        # The same level with new numbers is not a state change; a different level must be seen
        # debounce_samples times in a row before it is adopted.
        if level is current.level:
            mon.candidate = None
            return []
        if mon.candidate is not None and mon.candidate[0] is level:
            mon.candidate_count += 1
        else:
            mon.candidate = (level, reasons)
            mon.candidate_count = 1
        if mon.candidate_count >= mon.debounce_samples:
            mon.candidate = None
            return self._publish(name, level, reasons, mon.values)
        return []

    def _publish(
        self,
        name: str,
        level: Level,
        reasons: tuple[str, ...],
        values: tuple[tuple[str, float], ...],
    ) -> list[SensorState]:
        if self._published[name].level is level:
            return []
        state = SensorState(name, level, reasons, values)
        self._published[name] = state
        return [state]
