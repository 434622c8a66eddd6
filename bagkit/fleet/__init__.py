"""Many bags at once on Dask (``dask.distributed``): statistics, catalogue, DataFrames.

See docs/fleet.md. A local cluster is started on 127.0.0.1 when no scheduler is given. The
names below are imported on first use: ``bagkit stats summary BAG`` needs ``expand_bags`` and
the cluster rule, not the Dask-facing modules behind the others.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bagkit.fleet.errors import CatalogError, FleetError, NoBagsError, SchedulerError

if TYPE_CHECKING:
    from bagkit.fleet.cluster import fleet_client, local_cluster
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


# Import statements, not importlib: ``-X importtime`` and the layering test see them.
def __getattr__(name: str) -> object:
    if name == "dataframe":
        from bagkit.fleet import frames

        return getattr(frames, name)
    if name == "expand_bags":
        from bagkit.fleet import inputs

        return getattr(inputs, name)
    if name in ("fleet_client", "local_cluster"):
        from bagkit.fleet import cluster

        return getattr(cluster, name)
    if name == "summarize_fleet":
        from bagkit.fleet import stats

        return getattr(stats, name)
    raise AttributeError(f"module 'bagkit.fleet' has no attribute {name!r}")
