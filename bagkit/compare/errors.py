"""Errors raised while comparing bags."""

from __future__ import annotations

from bagkit.errors import BagkitError


class CompareError(BagkitError):
    """A comparison that cannot be made: unreadable bag, unknown topic, bad tolerance spec."""

    exit_code = 2
