"""One fixture in one mode: lockstep (:mod:`~bagkit.regression.golden`) or live
(:mod:`~bagkit.regression.live`), chosen here so that neither imports the other's caller."""

from __future__ import annotations

from pathlib import Path

from bagkit.regression.golden import GoldenCheck, check_lockstep
from bagkit.regression.spec import FixtureSpec


def run_check(spec: FixtureSpec, mode: str, workdir: Path) -> GoldenCheck:
    """Check ``spec`` in ``mode`` (``lockstep`` or ``live``) in ``workdir``.

    Raises:
        SpecError: the spec does not describe the system for ``mode``.
        LiveRunError: a live run failed.
    """
    if mode == "live":
        # The live run needs rclpy: only a live check pays for its import.
        from bagkit.regression.live import check_live

        return check_live(spec, workdir)
    return check_lockstep(spec, workdir)
