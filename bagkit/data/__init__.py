"""Looking at the data of a bag: DataFrames and Arrow tables, echo, export, plots.

``read_dataframe``/``read_arrow`` (:mod:`bagkit.data.frames`) are the notebook API; the
``bagkit echo``, ``export`` and ``plot`` commands are built on the same modules. pandas and
pyarrow are imported on first use of what needs them (``bagkit echo`` starts without them).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bagkit.data.errors import (
    DataError,
    DataLossWarning,
    UndecodableTopicError,
    UnknownFieldError,
    UnknownTopicError,
)

if TYPE_CHECKING:
    from bagkit.data.frames import read_arrow, read_dataframe

__all__ = [
    "DataError",
    "DataLossWarning",
    "UndecodableTopicError",
    "UnknownFieldError",
    "UnknownTopicError",
    "read_arrow",
    "read_dataframe",
]


def __getattr__(name: str) -> object:
    if name in ("read_arrow", "read_dataframe"):
        from bagkit.data import frames

        return getattr(frames, name)
    raise AttributeError(f"module 'bagkit.data' has no attribute {name!r}")
