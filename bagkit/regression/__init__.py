"""Golden-bag regression for any ROS 2 system: specs, lockstep and live runs, reports.

The public API: ``Processor`` (what a lockstep factory returns), ``load_spec`` and
``find_fixtures`` (fixture specs), ``check_lockstep``, ``check_live``, ``update_golden``,
``record_golden`` and ``write_failure_artefacts``. Importing this package imports no rclpy.
"""

from __future__ import annotations

from bagkit.regression.errors import LiveRunError, RegressionError, SpecError
from bagkit.regression.processor import Output, Processor
from bagkit.regression.spec import FixtureSpec, find_fixtures, load_spec

__all__ = [
    "FixtureSpec",
    "LiveRunError",
    "Output",
    "Processor",
    "RegressionError",
    "SpecError",
    "find_fixtures",
    "load_spec",
]
