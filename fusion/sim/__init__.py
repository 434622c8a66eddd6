"""The simulated flight that drives every sensor."""

from __future__ import annotations

from fusion.sim.trajectory import FlightProfile, TrajectoryState, trajectory_state

__all__ = ["FlightProfile", "TrajectoryState", "trajectory_state"]
