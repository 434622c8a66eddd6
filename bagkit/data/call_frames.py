"""``read_calls``: a recorded service's calls as a pandas DataFrame, paired as ``echo`` pairs
them (``read_dataframe`` of its event topic gives the events one by one)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.data.services import echo_calls
from bagkit.selection.query import Query
from bagkit.selection.times import TimeLike

if TYPE_CHECKING:
    import pandas as pd

# The columns of every call, before its request's and response's fields.
CALL_COLUMNS = ("log_time", "client_gid", "sequence_number", "events", "latency_s", "latency_side")


def read_calls(
    bag: str | Path,
    service: str,
    start: TimeLike | None = None,
    end: TimeLike | None = None,
    where: str | None = None,
) -> pd.DataFrame:
    """The calls of ``service`` in ``bag``, one row each, indexed by the log time of the call's
    first event (``time``, ``datetime64[ns]`` UTC).

    Args:
        bag: a bag directory or file.
        service: the service's name (``/logger/get_summary``).
        start, end: the calls in ``start <= log_time < end``, as :func:`read_dataframe` reads
            them.
        where: only the calls satisfying this condition, as ``echo --where`` reads it
            (``'response.success == false or latency_s > 0.1'``).

    Columns as ``bagkit echo BAG SERVICE --format json`` prints a call: ``log_time`` (ns),
    ``client_gid`` (hex), ``sequence_number``, ``events`` (the kinds seen), ``latency_s``
    (NaN where neither side recorded both its events), ``latency_side``, then the fields of
    the request and the response as ``request.PATH`` and ``response.PATH``.

    Example:
        >>> calls = bagkit.read_calls("flight1", "/logger/get_summary")
        >>> calls["latency_s"].describe()

    Raises:
        UndecodableTopicError: the bag has no such service, or its events do not decode.
        UnknownFieldError, SelectionError: ``where`` does not fit the service's calls.
    """
    import pandas as pd

    query = Query.create(start=start, end=end, where=where, prefix="")
    records = [
        {k: v for k, v in call.items() if k not in ("topic", "service")}
        for call in echo_calls(bag, service, query=query)
    ]
    frame = pd.json_normalize(records, sep=".") if records else pd.DataFrame()
    parts = frame.columns.drop(list(CALL_COLUMNS), errors="ignore")  # request.*, response.*
    frame = frame.reindex(columns=[*CALL_COLUMNS, *parts])
    frame["log_time"] = frame["log_time"].astype("int64")
    frame["latency_s"] = frame["latency_s"].astype("float64")
    frame.index = pd.DatetimeIndex(pd.to_datetime(frame["log_time"], unit="ns", utc=True))
    frame.index.name = "time"
    return frame
