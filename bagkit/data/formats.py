"""File formats of an export (apart from the writer, so that the CLI imports no pyarrow)."""

from __future__ import annotations

from bagkit.compat import StrEnum


class ExportFormat(StrEnum):
    """File formats of an export."""

    PARQUET = "parquet"
    CSV = "csv"
