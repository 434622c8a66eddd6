"""Fault schedules: which sensor misbehaves when, so that alerts really fire.

A schedule is written as comma-separated entries ``KIND@START+DURATION[=MAGNITUDE]``, times in
seconds since the sensor publisher started, for example
``temperature_spike@6+2, pressure_spike@9+1.5=15000, gps_loss@12+4, imu_stuck@16+2``. A
dropout names the sensor that falls silent: ``dropout:gps@20+3`` (``dropout`` alone: the IMU).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from bagkit.compat import StrEnum
from fusion.errors import FaultScheduleError


class FaultKind(StrEnum):
    """What goes wrong."""

    TEMPERATURE_SPIKE = "temperature_spike"  # adds MAGNITUDE degrees C
    PRESSURE_SPIKE = "pressure_spike"  # adds MAGNITUDE Pa
    GPS_LOSS = "gps_loss"  # the receiver reports no fix
    IMU_STUCK = "imu_stuck"  # the IMU repeats its last sample
    DROPOUT = "dropout"  # a sensor publishes nothing


# The sensors a dropout can silence (the sensor publisher's names); the first is the default.
SENSORS = ("imu", "gps", "temperature", "pressure")


DEFAULT_MAGNITUDES: dict[FaultKind, float] = {
    FaultKind.TEMPERATURE_SPIKE: 60.0,
    FaultKind.PRESSURE_SPIKE: 15000.0,
    FaultKind.GPS_LOSS: 0.0,
    FaultKind.IMU_STUCK: 0.0,
    FaultKind.DROPOUT: 0.0,
}

_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"
_ENTRY = re.compile(
    rf"^(?P<kind>[a-z_]+)(?::(?P<sensor>[a-z_]+))?@(?P<start>{_NUMBER})\+(?P<duration>{_NUMBER})"
    rf"(?:=(?P<magnitude>{_NUMBER}))?$"
)


@dataclass(frozen=True, slots=True)
class Fault:
    """One scheduled fault, active for ``start <= t < start + duration`` (seconds).

    ``sensor``: the sensor a dropout silences (empty for the other kinds).
    """

    kind: FaultKind
    start: float
    duration: float
    magnitude: float
    sensor: str = ""

    def active(self, t: float) -> bool:
        """Whether the fault is active ``t`` seconds after the start."""
        return self.start <= t < self.start + self.duration

    @property
    def label(self) -> str:
        """The fault as a schedule names it: ``gps_loss``, ``dropout:gps``."""
        return f"{self.kind.value}:{self.sensor}" if self.sensor else self.kind.value


@dataclass(frozen=True, slots=True)
class FaultSchedule:
    """A set of faults; ``period`` > 0 repeats the schedule every ``period`` seconds."""

    faults: tuple[Fault, ...] = ()
    period: float = 0.0

    @classmethod
    def parse(cls, text: str, *, period: float = 0.0) -> FaultSchedule:
        """Parse ``KIND@START+DURATION[=MAGNITUDE], ...`` (empty text: no faults).

        Raises:
            FaultScheduleError: an entry is malformed or names an unknown kind.
        """
        faults = []
        for raw in text.split(","):
            entry = raw.strip().replace(" ", "")
            if not entry:
                continue
            match = _ENTRY.match(entry)
            if match is None:
                raise FaultScheduleError(
                    f"bad fault {raw.strip()!r}: expected KIND@START+DURATION[=MAGNITUDE]"
                )
            try:
                kind = FaultKind(match["kind"])
            except ValueError:
                known = ", ".join(k.value for k in FaultKind)
                raise FaultScheduleError(
                    f"unknown fault kind {match['kind']!r} (known: {known})"
                ) from None
            magnitude = match["magnitude"]
            faults.append(
                Fault(
                    kind=kind,
                    start=float(match["start"]),
                    duration=float(match["duration"]),
                    magnitude=DEFAULT_MAGNITUDES[kind] if magnitude is None else float(magnitude),
                    sensor=_sensor(kind, match["sensor"], raw.strip()),
                )
            )
        if period < 0 or not math.isfinite(period):
            raise FaultScheduleError(f"fault period must be >= 0, got {period}")
        return cls(tuple(faults), period)

    def active(self, kind: FaultKind, t: float, sensor: str = "") -> Fault | None:
        """The fault of ``kind`` (of ``sensor``, for a dropout) active at ``t`` seconds."""
        for fault in self.active_faults(t):
            if fault.kind is kind and fault.sensor == sensor:
                return fault
        return None

    def active_faults(self, t: float) -> list[Fault]:
        """Every fault active at ``t`` seconds."""
        if self.period > 0:
            t = math.fmod(t, self.period)
        return [fault for fault in self.faults if fault.active(t)]


def _sensor(kind: FaultKind, sensor: str | None, entry: str) -> str:
    """The sensor of a dropout (default: the IMU); other kinds name none.

    Raises:
        FaultScheduleError: a sensor on another kind, or an unknown sensor.
    """
    if kind is not FaultKind.DROPOUT:
        if sensor is not None:
            raise FaultScheduleError(f"bad fault {entry!r}: only a dropout names a sensor")
        return ""
    if sensor is None:
        return SENSORS[0]
    if sensor not in SENSORS:
        raise FaultScheduleError(
            f"bad fault {entry!r}: unknown sensor {sensor!r} (known: {', '.join(SENSORS)})"
        )
    return sensor
