"""One fixture in one mode: lockstep (:mod:`~bagkit.regression.golden`) or live
(:mod:`~bagkit.regression.live`), chosen here so that neither imports the other's caller."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from bagkit.health import check_bag
from bagkit.regression.golden import GoldenCheck, check_lockstep
from bagkit.regression.health import outputs_contract
from bagkit.regression.spec import FixtureSpec


def run_check(spec: FixtureSpec, mode: str, workdir: Path) -> GoldenCheck:
    """Check ``spec`` in ``mode`` (``lockstep`` or ``live``) in ``workdir``; with a
    ``health:`` contract, check it on the golden and on the candidate too.

    Raises:
        SpecError: the spec does not describe the system for ``mode``.
        LiveRunError: a live run failed.
    """
    if mode == "live":
        # The live run needs rclpy: only a live check pays for its import.
        from bagkit.regression.live import check_live

        check = check_live(spec, workdir)
    else:
        check = check_lockstep(spec, workdir)
    if spec.health is None or check.drift:  # a drifted golden is not run: no candidate
        return check
    return replace(
        check,
        health=check_bag(check.candidate, outputs_contract(spec.health, spec.outputs)),
        golden_health=check_bag(spec.bag, spec.health),
    )
