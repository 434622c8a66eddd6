"""The message-by-message copy: any inputs (MCAP, SQLite3, ROS 1) into an MCAP or SQLite3 bag.

What ``filter``, ``merge`` and ``convert`` do when chunks cannot be copied as stored: an input
that is not MCAP, or an output that is not. The inputs' messages are merged in log-time order
(ties: the order the bags are given) through :class:`~bagkit.bag.reader.BagReader`, so every
storage back-end reads the same way; the selection is the one of the chunk copy (topics, time
window, ``--where`` content, latched state before the window).
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from bagkit.bag import BagMessage, BagReader
from bagkit.bag.messages import TopicInfo, make_message
from bagkit.surgery.assumed import check_assumed_definitions
from bagkit.surgery.carry import latched_messages, merged_custom_data, write_latched
from bagkit.surgery.chunk_records import Progress, copy_chunk_records
from bagkit.surgery.errors import SurgeryError, holding_no_topic
from bagkit.surgery.options import (
    OutputOptions,
    PayloadRewrites,
    RewriteReport,
    TopicRewrite,
    resolve,
)
from bagkit.surgery.output import MessageOutput, OutputBag
from bagkit.surgery.select import PayloadFilter, Selection

# Messages written at once (and progress reported): 1-2 MB of Imu messages.
_BATCH = 4096
_ZERO = np.zeros(1, np.int64)


def open_output(output: Path, options: OutputOptions) -> MessageOutput:
    """The output bag in ``options.storage``.

    Raises:
        SurgeryError: an unknown storage, or what the output's constructor raises.
    """
    if options.storage == "sqlite3":
        from bagkit.surgery.sqlite3_output import Sqlite3OutputBag

        return Sqlite3OutputBag(output, options)
    if options.storage != "mcap":
        raise SurgeryError(f"storage {options.storage!r}: bagkit writes mcap or sqlite3")
    return OutputBag.create(output, options)


def rewrite_messages(
    bags: Sequence[Path],
    output: Path,
    selection: Selection,
    options: OutputOptions,
    progress: Progress | None = None,
    *,
    rewrites: PayloadRewrites | None = None,
) -> RewriteReport:
    """Copy the messages of ``bags`` that ``selection`` keeps into a new bag ``output``
    (the payloads of ``rewrites``' topics rewritten).

    Raises:
        BagError: an input cannot be opened. SurgeryError: a topic with two types, nothing
        selected, or the output cannot be written.
    """
    report = RewriteReport(output=output)
    with contextlib.ExitStack() as stack:
        readers = [stack.enter_context(BagReader(bag, allow_empty=True)) for bag in bags]
        known, definitions = _topics(readers)
        spans = [(r.start_ns, r.end_ns) for r in readers if r.message_count]
        selection = resolve(selection, bags, set(known), spans, report)
        latched = latched_messages(bags, known, selection)
        selected = [name for name in known if selection.topic_passes(name)]
        if not known:
            raise holding_no_topic(bags)
        if not selected:
            raise SurgeryError("no topic is selected")
        for reader in readers:
            check_assumed_definitions(reader, selected)
        out = open_output(output, options)
        try:
            out.custom_data = merged_custom_data(
                [
                    (b.name, dict(r.metadata.custom_data) if r.metadata else {})
                    for b, r in zip(bags, readers, strict=True)
                ]
            )
            rewritten = rewrites.topics if rewrites is not None else {}
            out.custom_data.update(rewrites.custom_data if rewrites is not None else {})
            for name in selected:
                topic = known[name]
                if name in rewritten:
                    out.add_topic(rewritten[name].topic, rewritten[name].definition, 0)
                else:
                    out.add_topic(topic, definitions.get(topic.type), 0)
            if latched and selection.window.start_ns is not None:
                write_latched(out, latched, selection.window.start_ns)
            total = sum(r.topic_counts.get(n, 0) for r in readers for n in selected)
            if len(readers) == 1 and isinstance(out, OutputBag) and not rewritten:
                report.problems += copy_chunk_records(
                    readers[0], set(selected), selection, out, (progress, total)
                )
            else:
                _copy(readers, set(selected), selection, out, (progress, total), rewritten)
            report.files = out.commit()
        except BaseException:
            out.abort()
            raise
        report.problems += [p for r in readers for p in r.problems]
        report.input_messages = sum(r.message_count for r in readers)
    report.problems += [f.problem for f in selection.content.values() if f.problem]
    report.topic_counts = {n: out.counts[out.topic_id(n)] for n in selected}
    report.latched_messages = len(latched)
    return report


def _topics(readers: list[BagReader]) -> tuple[dict[str, TopicInfo], dict[str, str]]:
    """Every input's topics (a name must have one type) and definitions by type."""
    known: dict[str, TopicInfo] = {}
    definitions: dict[str, str] = {}
    for reader in readers:
        for name, topic in reader.topics.items():
            first = known.setdefault(name, topic)
            if first.type != topic.type:
                raise SurgeryError(
                    f"{name} has type {first.type} in one input and {topic.type} in {reader.path}"
                )
        for type_name, text in reader.definitions.items():
            definitions.setdefault(type_name, text)
    return known, definitions


def _copy(  # noqa: PLR0917 (the copy's parts, passed as they are)
    readers: list[BagReader],
    selected: set[str],
    selection: Selection,
    out: MessageOutput,
    progress: tuple[Progress | None, int],
    rewritten: Mapping[str, TopicRewrite],
) -> None:
    """The selected messages of every reader, merged in log-time order, into ``out``."""
    window = selection.window
    streams = [
        r.messages(selected & r.topics.keys(), window.start_ns, window.end_ns) for r in readers
    ]
    merged = streams[0] if len(streams) == 1 else heapq.merge(*streams, key=_log_time)
    ids = {name: out.topic_id(name) for name in selected}
    content = selection.content
    report, total = progress
    done = 0
    while batch := list(itertools.islice(merged, _BATCH)):
        done += len(batch)
        if content:
            batch = [m for m in batch if _passes(content.get(m.topic), m)]
        if rewritten:
            batch = [_rewritten(rewritten.get(m.topic), m) for m in batch]
        out.write_messages([ids[m.topic] for m in batch], batch)
        if report is not None:
            report(done, total)


def _passes(matcher: PayloadFilter | None, message: BagMessage) -> bool:
    """Whether ``message`` passes its topic's ``--where`` filter (True without one)."""
    if matcher is None:
        return True
    lengths = np.array([len(message.data)], np.int64)
    times = np.array([message.log_time], np.int64)  # a condition over time reads them
    return bool(matcher.mask_records(message.data, _ZERO, lengths, times)[0])


def _rewritten(rewrite: TopicRewrite | None, message: BagMessage) -> BagMessage:
    if rewrite is None:
        return message
    data = rewrite.payload(message.data)
    return make_message(
        message.topic, data, message.log_time, message.publish_time, message.sequence
    )


def _log_time(message: BagMessage) -> int:
    return message.log_time
