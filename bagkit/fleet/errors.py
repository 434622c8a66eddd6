"""Errors of ``bagkit.fleet``."""

from __future__ import annotations

from bagkit.errors import OptionError


class FleetError(OptionError):
    """A many-bag run that cannot start or complete."""


class NoBagsError(FleetError):
    """The inputs name no bag (an empty directory, a glob matching nothing, an empty listing)."""


class SchedulerError(FleetError):
    """The Dask scheduler given with ``--scheduler`` cannot be reached."""


class CatalogError(FleetError):
    """A catalogue file that cannot be read or written."""
