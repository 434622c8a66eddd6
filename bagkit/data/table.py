"""All the rows of one topic, decoded straight into one preallocated array per column.

A DataFrame of a million messages is hundreds of MB: each column is written once, where it
will stay, and handed to pandas and Arrow without a copy (concatenating per-chunk pieces would
touch all of it twice).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from bagkit.data.columns import Rows, arrow_arrays, list_array, numpy_dtype
from bagkit.decode import LeafField

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa


class ColumnTable:
    """Rows appended chunk by chunk into arrays of ``capacity`` rows (grown if exceeded)."""

    def __init__(self, leaves: Sequence[LeafField], capacity: int) -> None:
        self.leaves = leaves
        self.size = 0
        self._arrays = [np.empty(capacity, dtype=numpy_dtype(leaf)) for leaf in leaves]
        self._times = [np.empty(capacity, dtype=np.int64) for _ in range(2)]
        self._ok = np.ones(capacity, dtype=bool)

    def reserve(self, n: int) -> Rows:
        """The next ``n`` rows, as views to fill."""
        if self.size + n > len(self._ok):  # the count in the index was short (salvaged bag)
            grown = max(2 * len(self._ok), self.size + n)
            self._arrays = [_grow(a, grown) for a in self._arrays]
            self._times = [_grow(a, grown) for a in self._times]
            self._ok = _grow(self._ok, grown, fill=True)
        part = slice(self.size, self.size + n)
        self.size += n
        return Rows(
            self.leaves,
            [a[part] for a in self._arrays],
            (self._times[0][part], self._times[1][part]),
            self._ok[part],
        )

    def columns(self) -> list[np.ndarray]:
        """log_time, publish_time, then the leaf arrays: decoded rows, in log-time order."""
        arrays = [a[: self.size] for a in (*self._times, *self._arrays)]
        ok = self._ok[: self.size]
        if not ok.all():
            arrays = [a[ok] for a in arrays]
        log_times = arrays[0]
        if len(log_times) > 1 and (np.diff(log_times) < 0).any():
            # Chunks overlap in time (or split files do): order like every reader does.
            order = np.argsort(log_times, kind="stable")
            arrays = [a[order] for a in arrays]
        return arrays

    def to_arrow(self, schema: pa.Schema) -> pa.Table:
        """The table (numeric columns shared with the arrays, not copied)."""
        import pyarrow as pa

        return pa.Table.from_arrays(
            arrow_arrays(self.leaves, self.columns(), schema), schema=schema
        )

    def to_pandas(self, schema: pa.Schema) -> pd.DataFrame:
        """A DataFrame of :meth:`columns` (numeric columns not copied), log time as index."""
        import pandas as pd
        import pyarrow as pa

        arrays = self.columns()
        data: dict[str, object] = {"log_time": arrays[0], "publish_time": arrays[1]}
        for leaf, field, array in zip(self.leaves, list(schema)[2:], arrays[2:], strict=True):
            if leaf.pooled:  # one numpy array of the element type per message
                lists = list_array(array, leaf, field.type)
                data[field.name] = lists.to_numpy(zero_copy_only=False)
            elif field.type == pa.string():
                data[field.name] = pd.array(array, dtype="str")
            else:
                data[field.name] = array
        index = pd.DatetimeIndex(arrays[0].view("datetime64[ns]"), name="time").tz_localize("UTC")
        return pd.DataFrame(data, index=index, copy=False)


def _grow(array: np.ndarray, size: int, *, fill: bool | None = None) -> np.ndarray:
    grown = np.empty(size, dtype=array.dtype) if fill is None else np.full(size, fill)
    grown[: len(array)] = array
    return grown
