"""Many bags at once on Dask (``dask.distributed``): statistics, catalogue, DataFrames.

See docs/fleet.md. A local cluster is started on 127.0.0.1 when no scheduler is given.
"""

from __future__ import annotations

from bagkit.fleet.cluster import fleet_client, local_cluster
from bagkit.fleet.errors import CatalogError, FleetError, NoBagsError, SchedulerError
from bagkit.fleet.frames import dataframe
from bagkit.fleet.inputs import expand_bags
from bagkit.fleet.stats import summarize_fleet

__all__ = [
    "CatalogError",
    "FleetError",
    "NoBagsError",
    "SchedulerError",
    "dataframe",
    "expand_bags",
    "fleet_client",
    "local_cluster",
    "summarize_fleet",
]
