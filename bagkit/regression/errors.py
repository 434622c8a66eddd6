"""Errors raised by the regression harness (fixture specs, lockstep and live runs)."""

from __future__ import annotations

from bagkit.errors import BagkitError


class RegressionError(BagkitError):
    """A regression run that could not be made."""

    exit_code = 2


class SpecError(RegressionError):
    """A fixture spec that is missing or invalid."""


class LiveRunError(RegressionError):
    """A live replay whose processes failed or did not produce a usable recording."""

    exit_code = 1
