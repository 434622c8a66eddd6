"""``bagkit export`` over many bags: each bag on one worker, into a folder of its own.

Each bag is exported by :func:`bagkit.data.export.export` exactly as it would be alone, under
``OUT/<the bag's path relative to the bags' common folder>`` (``flights/day1/bag_00`` and
``flights/day2/bag_00`` -> ``OUT/day1/bag_00/``, ``OUT/day2/bag_00/``), so that the files do not
depend on where the task ran. The workers write the files: ``OUT`` must be at the same path on
every worker (always so on a local cluster). A bag that cannot be exported is reported in its
:class:`BagExport`; the others complete.
"""

from __future__ import annotations

import functools
import os
import posixpath
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any

from bagkit.data.export import ExportReport, export
from bagkit.data.formats import ExportFormat
from bagkit.errors import BagkitError
from bagkit.fleet.errors import FleetError
from bagkit.fleet.execute import ItemDone, run_each
from bagkit.selection.query import Query
from bagkit.storage.urls import is_url, location, path_part, shown_as

if TYPE_CHECKING:
    from distributed import Client


@dataclass(frozen=True, slots=True)
class BagExport:
    """What the export of one bag wrote (``report``) or why it could not (``error``)."""

    bag: str
    out: Path
    report: ExportReport | None = None
    error: str | None = None


def bag_folders(bags: Sequence[str | Path], out: Path) -> list[Path]:
    """Where each bag's files go: its path relative to the bags' common folder, under ``out``.

    Raises:
        FleetError: two bags would share a folder (``a.mcap`` beside a directory ``a``).
    """
    if any(is_url(bag) for bag in bags):  # in storage: by the URLs' paths
        names = [path_part(location(bag)).split("://", 1)[-1] for bag in bags]
        common_url = posixpath.commonpath([posixpath.dirname(n) for n in names])
        folders = [out / _stem(posixpath.relpath(n, common_url)) for n in names]
    else:
        paths = [Path(bag).resolve() for bag in bags]
        common = Path(os.path.commonpath([p.parent for p in paths]))
        folders = [
            out / (p.relative_to(common).with_suffix("") if p.is_file() else p.relative_to(common))
            for p in paths
        ]
    if len(set(folders)) < len(folders):
        twice = sorted({str(f) for f in folders if folders.count(f) > 1})
        raise FleetError(f"several bags would be exported into {twice[0]}: rename one")
    return folders


def _stem(name: str) -> str:
    """A bag file's name without its storage suffix (``a.mcap``: ``a``)."""
    return (
        name[: -len(suffix)]
        if (suffix := PurePosixPath(name).suffix) in (".mcap", ".db3", ".bag")
        else name
    )


def export_bag(job: tuple[str, Path], **options: Any) -> BagExport:
    """Export one bag (what a worker runs); ``options`` as :func:`bagkit.data.export.export`."""
    path, out = job
    bag = shown_as(path)  # opened in full, named without a URL's secrets
    try:
        report = export(path, out, **options)
    except BagkitError as exc:
        return BagExport(bag, out, error=str(exc))
    return BagExport(bag, out, report=report)


def export_fleet(
    bags: Sequence[str | Path],
    out: str | Path,
    *,
    client: Client | None = None,
    file_format: ExportFormat = ExportFormat.PARQUET,
    query: Query | None = None,
    dataset: bool = False,
    done: ItemDone | None = None,
) -> list[BagExport]:
    """Export every bag of ``bags`` into its folder under ``out``, on ``client``'s workers.

    ``query`` is resolved against each bag, as by a single-bag export (``--start 10`` is ten
    seconds after that bag's start). Results are in the order of ``bags``.

    Raises:
        FleetError: ``out`` is a file name, or two bags would share a folder.
    """
    out = Path(out)
    if out.suffix in (".parquet", ".csv"):
        raise FleetError(f"{out} is a file name: several bags are exported into a directory")
    folders = bag_folders(bags, out)
    task = functools.partial(
        export_bag,
        file_format=ExportFormat(file_format),
        query=query,
        dataset=dataset,
    )
    jobs = [(location(bag), folder) for bag, folder in zip(bags, folders, strict=True)]
    return run_each(task, jobs, client, done)
