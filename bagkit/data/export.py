"""Topics of a bag to Parquet (zstd) or CSV, streamed: memory stays bounded by a row group.

Parquet files hold the columns of :func:`bagkit.read_arrow` (list columns for sequences); CSV
files the same columns, sequences as JSON text. Output: one file per topic under a directory
(``/imu/data`` -> ``OUT/imu/data.parquet``), one file when a single topic is exported to a path
ending in ``.parquet``/``.csv``, or with ``dataset=True`` a folder of part files per topic that
``pandas.read_parquet(folder)`` and ``pyarrow.dataset`` read as one table.
"""

from __future__ import annotations

import json
import warnings
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from bagkit.bag import BagReader
from bagkit.data.errors import DataError, could_have_lost, unread_topics
from bagkit.data.formats import ExportFormat
from bagkit.data.scan import Scan, plan_scan
from bagkit.selection.errors import EmptyWindowWarning
from bagkit.selection.query import Query

# A row group is written once this many rows or bytes of a topic are buffered.
ROW_GROUP_ROWS = 128 * 1024
ROW_GROUP_BYTES = 32 << 20
# Dataset folders start a new part file after this many rows.
ROWS_PER_PART = 1 << 20

ProgressCallback = Callable[[int, int], None]
"""Called with (messages done, messages in total)."""


@dataclass(slots=True)
class ExportReport:
    """What an export wrote and what it could not.

    Attributes:
        files: topic -> the files written for it.
        rows: topic -> rows written.
        skipped: topic -> why it was not exported (cannot be decoded).
        problems: what was lost (unreadable parts of the bag, messages that do not decode).
        messages: topic -> its messages read (in the window, before the condition kept some).
        undecodable: topic -> those of them that did not decode (not in the rows).
        lost: the parts of the bag that could not be read (damaged chunks; in ``problems``).
        losing: the topics whose messages may be among them
            (:func:`~bagkit.data.errors.could_have_lost`).
    """

    files: dict[str, list[Path]] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    messages: dict[str, int] = field(default_factory=dict)
    undecodable: dict[str, int] = field(default_factory=dict)
    lost: list[str] = field(default_factory=list)
    losing: list[str] = field(default_factory=list)


def none_decoded_topics(reports: Iterable[ExportReport]) -> dict[str, int]:
    """Topic -> its messages, for the topics that had messages in the exports of ``reports``
    (one bag's, or a fleet's) and decoded none of them in any."""
    messages: Counter[str] = Counter()
    undecodable: Counter[str] = Counter()
    for report in reports:
        messages.update(report.messages)
        undecodable.update(report.undecodable)
    return {t: n for t, n in messages.items() if 0 < n == undecodable[t]}


def nothing_read_topics(reports: Iterable[ExportReport]) -> tuple[list[str], list[str]]:
    """(topics, what was lost): the topics exported from ``reports`` (one bag's, or a fleet's)
    no message of which was read in any, when a bag lost parts that could have held some;
    none else (an empty topic, a window without its messages: empty files are the answer)."""
    reports = list(reports)
    losing = {topic for report in reports for topic in report.losing}
    counts = (pair for report in reports for pair in report.messages.items())
    lost = [problem for report in reports for problem in report.lost]
    return unread_topics(counts, losing), lost


def topic_path(out: Path, topic: str, suffix: str) -> Path:
    """``OUT/imu/data.parquet`` for ``/imu/data``: the topic's namespaces become folders."""
    parts = [part for part in topic.split("/") if part not in ("", ".", "..")]
    return out.joinpath(*parts).with_name(parts[-1] + suffix) if parts else out / f"_{suffix}"


def export(
    bag: str | Path,
    out: str | Path,
    *,
    file_format: ExportFormat = ExportFormat.PARQUET,
    query: Query | None = None,
    dataset: bool = False,
    progress: ProgressCallback | None = None,
) -> ExportReport:
    """Write the decodable topics ``query`` names (all when none) of ``bag`` under ``out``.

    ``query``'s fields, times and condition as :func:`~bagkit.data.scan.plan_scan` applies
    them: with several topics, those lacking the fields or the condition's fields are left out.

    Raises:
        BagError, UnknownTopicError, UnknownFieldError; DataError when no topic can be
        exported or ``out`` names a single file for several topics; SelectionError for a
        condition that does not parse or compares text with a number.
    """
    out, file_format = Path(out), ExportFormat(file_format)
    with BagReader(bag, allow_empty=True) as reader:
        scan = plan_scan(reader, query or Query(), label=str(bag))
        report = ExportReport(skipped=dict(scan.skipped))
        if scan.outside is not None:
            warnings.warn(scan.outside, EmptyWindowWarning, stacklevel=2)
        if not scan.topics:
            reasons = "; ".join(f"{t}: {why}" for t, why in scan.skipped.items())
            raise DataError(f"no topic of {reader.path} can be exported ({reasons or 'none'})")
        single = out.suffix in (".parquet", ".csv")
        if single and (len(scan.topics) > 1 or dataset):
            raise DataError(
                f"{out} is a file but {len(scan.topics)} topics are exported: give a directory"
            )
        sinks = {
            topic: _Sink(
                out if single else topic_path(out, topic, "" if dataset else f".{file_format}"),
                columns.schema,
                file_format,
                dataset=dataset,
            )
            for topic, columns in scan.topics.items()
        }
        total = sum(reader.topic_counts.get(topic, 0) for topic in scan.topics)
        _write(scan, sinks, total, progress)
        report.problems = scan.problems
        report.lost = list(reader.problems)
        report.losing = [t for t in scan.topics if could_have_lost(reader, t)]
    for topic, sink in sinks.items():
        report.files[topic] = sink.files
        report.rows[topic] = sink.rows
        report.messages[topic] = scan.topics[topic].messages
        report.undecodable[topic] = scan.topics[topic].undecodable
    return report


def _write(
    scan: Scan, sinks: dict[str, _Sink], total: int, progress: ProgressCallback | None
) -> None:
    done = 0
    try:
        for topic, batch in scan.batches():
            sinks[topic].add(batch)
            done += batch.num_rows
            if progress is not None:
                progress(done, total)
    finally:
        for sink in sinks.values():
            sink.close()
    if progress is not None:
        progress(total, total)


class _Sink:
    """The file(s) of one topic: buffers batches into row groups, rolls dataset parts."""

    def __init__(
        self, path: Path, schema: pa.Schema, file_format: ExportFormat, *, dataset: bool
    ) -> None:
        self.path = path
        self.schema = schema
        self.format = file_format
        self.dataset = dataset
        self.files: list[Path] = []
        self.rows = 0
        self._pending: list[pa.RecordBatch] = []
        self._pending_rows = 0
        self._pending_bytes = 0
        self._writer: Any = None
        self._part_rows = 0

    def add(self, batch: pa.RecordBatch) -> None:
        if not batch.num_rows:  # no message of the chunk decoded: nothing to write
            return
        self._pending.append(batch)
        self._pending_rows += batch.num_rows
        self._pending_bytes += batch.nbytes
        if self._pending_rows >= ROW_GROUP_ROWS or self._pending_bytes >= ROW_GROUP_BYTES:
            self._flush()

    def close(self) -> None:
        self._flush()
        if self._writer is None and not self.files:
            self._open()  # an empty topic still gets its file, with the columns
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def _flush(self) -> None:
        if not self._pending:
            return
        table = pa.Table.from_batches(self._pending, schema=self.schema)
        self._pending, self._pending_rows, self._pending_bytes = [], 0, 0
        if self.dataset and self._writer is not None and self._part_rows >= ROWS_PER_PART:
            self._writer.close()
            self._writer = None
        if self._writer is None:
            self._open()
        if self.format is ExportFormat.CSV:
            self._writer.write_table(_json_lists(table))
        else:
            self._writer.write_table(table, row_group_size=len(table))
        self.rows += len(table)
        self._part_rows += len(table)

    def _open(self) -> None:
        path = self.path / f"part-{len(self.files):05d}.parquet" if self.dataset else self.path
        path.parent.mkdir(parents=True, exist_ok=True)
        if self.format is ExportFormat.CSV:
            self._writer = pa_csv.CSVWriter(path, _json_lists_schema(self.schema))
        else:
            # Dictionaries for strings only: trying one on every float column (pyarrow's
            # default) makes writing several times slower, and zstd packs them anyway.
            strings = [f.name for f in self.schema if f.type == pa.string()]
            self._writer = pq.ParquetWriter(
                path, self.schema, compression="zstd", use_dictionary=strings
            )
        self.files.append(path)
        self._part_rows = 0


def _json_lists_schema(schema: pa.Schema) -> pa.Schema:
    return pa.schema(
        [pa.field(f.name, pa.string()) if pa.types.is_list(f.type) else f for f in schema]
    )


def _json_lists(table: pa.Table) -> pa.Table:
    """List columns as JSON text (NaN and infinities as ``NaN``/``Infinity``), for CSV."""
    for i, column in enumerate(table.schema):
        if pa.types.is_list(column.type):
            texts = [json.dumps(v, ensure_ascii=False) for v in table.column(i).to_pylist()]
            table = table.set_column(i, column.name, pa.array(texts, type=pa.string()))
    return table
