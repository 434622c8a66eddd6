"""Running statistics per numeric field of one message stream, with bagkit's ``Moments``.

Messages are buffered as rows and handed to ``Moments`` in one batch when the figures are read
(the data logger reads them once per summary), so the per-message cost is a list append.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import astuple, dataclass

import numpy as np

from bagkit.stats import Moments


@dataclass(frozen=True, slots=True)
class FieldFigures:
    """One field's figures: NaN samples counted apart and left out of the others;
    ``std`` of the population (numpy's default ``ddof=0``); NaN where there are no values."""

    count: int
    nan_count: int
    min: float
    max: float
    mean: float
    std: float

    def row(self) -> tuple[float, ...]:
        """count, nan_count, min, max, mean, std."""
        return astuple(self)


class StreamMoments:
    """Count, min, max, mean and std of every numeric field of one stream of messages.

    The fields are those of the first message (a message type has a fixed set of numeric
    fields); later messages are read by those names.
    """

    def __init__(self) -> None:
        self.messages = 0
        self.names: tuple[str, ...] = ()
        self._pending: list[list[float]] = []
        self._moments: Moments | None = None

    def add(self, values: Mapping[str, float]) -> None:
        """Add one message's numeric fields (name -> value)."""
        if self._moments is None:
            self.names = tuple(values)
            self._moments = Moments(len(self.names))
        self.messages += 1
        self._pending.append([values[name] for name in self.names])

    def fields(self) -> Iterator[tuple[str, FieldFigures]]:
        """Each field's name and figures so far, in the first message's field order."""
        moments = self._moments
        if moments is None:
            return
        if self._pending:
            moments.add(np.array(self._pending, dtype=np.float64).reshape(-1, len(self.names)))
            self._pending.clear()
        columns = zip(
            moments.count.tolist(),
            moments.nan_count.tolist(),
            moments.min.tolist(),
            moments.max.tolist(),
            moments.mean.tolist(),
            moments.std(ddof=0).tolist(),
            strict=True,
        )
        for name, figures in zip(self.names, columns, strict=True):
            yield name, FieldFigures(*figures)
