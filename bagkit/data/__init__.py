"""Looking at the data of a bag: DataFrames and Arrow tables, echo, export, plots.

``read_dataframe``/``read_arrow`` (:mod:`bagkit.data.frames`) are the notebook API; the
``bagkit echo``, ``export`` and ``plot`` commands are built on the same modules.
"""

from __future__ import annotations

from bagkit.data.errors import (
    DataError,
    UndecodableTopicError,
    UnknownFieldError,
    UnknownTopicError,
)
from bagkit.data.frames import DataLossWarning, read_arrow, read_dataframe

__all__ = [
    "DataError",
    "DataLossWarning",
    "UndecodableTopicError",
    "UnknownFieldError",
    "UnknownTopicError",
    "read_arrow",
    "read_dataframe",
]
