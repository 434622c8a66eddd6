"""``filter``, ``merge``, ``recover`` and ``convert``: open the inputs, copy, commit the output.

MCAP inputs into an MCAP output are copied chunk by chunk (:mod:`~bagkit.surgery.copy`); any
other input (SQLite3, ROS 1) or output (SQLite3) message by message
(:mod:`~bagkit.surgery.message_copy`), with the same selection.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bagkit.bag import BagError, BagReader
from bagkit.bag.mcap_file import McapFile
from bagkit.bag.mcapio import MAGIC, FileIndex, Source, read_file_index
from bagkit.bag.metadata import METADATA_FILENAME, read_metadata
from bagkit.bag.storage_files import message_compressed
from bagkit.surgery.carry import latched_messages, merged_custom_data, write_latched
from bagkit.surgery.content import with_content
from bagkit.surgery.copy import CopyOptions, InputFile, copy_files, topics_of
from bagkit.surgery.errors import SurgeryError, holding_no_topic
from bagkit.surgery.options import OutputOptions, PayloadRewrites, RewriteReport, resolve
from bagkit.surgery.output import OutputBag
from bagkit.surgery.output_paths import single_file
from bagkit.surgery.select import Selection


def filter_bag(
    bag: Path, output: Path, selection: Selection, options: OutputOptions | None = None
) -> RewriteReport:
    """Write the messages of ``bag`` that ``selection`` keeps to a new bag ``output``; with a
    start, the latched state before it first (:mod:`~bagkit.surgery.carry`).

    Raises:
        BagError: the input cannot be opened. SurgeryError: see :class:`OutputBag`.
    """
    return _rewrite([bag], output, selection, options or OutputOptions())


def merge_bags(
    bags: Sequence[Path],
    output: Path,
    selection: Selection | None = None,
    options: OutputOptions | None = None,
) -> RewriteReport:
    """Merge ``bags`` into one new bag stored in log-time order (ties: in the order given).

    Chunks stored out of log-time order (per-topic batches) are opened and written in order.
    """
    if not bags:
        raise SurgeryError("no input bag")
    selection = selection or Selection()
    return _rewrite(list(bags), output, selection, options or OutputOptions(), stored_order=True)


def recover_bag(bag: Path, output: Path, options: OutputOptions | None = None) -> RewriteReport:
    """Rewrite a crashed, truncated or index-less bag as a complete one; report what was lost."""
    return _rewrite([bag], output, Selection(), options or OutputOptions())


def rewrite_topics(
    bag: Path, output: Path, rewrites: PayloadRewrites, options: OutputOptions | None = None
) -> RewriteReport:
    """Copy ``bag`` whole into ``output``, the payloads of ``rewrites``' topics rewritten
    (``bagkit migrate``): chunks without them copied as stored, the others opened."""
    return _rewrite([bag], output, Selection(), options or OutputOptions(), rewrites=rewrites)


def _rewrite(
    bags: list[Path],
    output: Path,
    selection: Selection,
    options: OutputOptions,
    *,
    stored_order: bool = False,
    rewrites: PayloadRewrites | None = None,
) -> RewriteReport:
    check_output(bags, output, options)
    selection = with_content(bags, selection)
    rewrites = rewrites or PayloadRewrites()
    scanned = ScannedFiles()
    if options.storage != "mcap" or not chunks_copyable(bags, scanned):
        from bagkit.surgery.message_copy import rewrite_messages

        return rewrite_messages(bags, output, selection, options, rewrites=rewrites)
    report = RewriteReport(output=output)
    inputs = _Inputs()
    with _opened_inputs(bags, report, inputs, scanned) as files:
        names = {name for f in files for name in f.known}
        if not names:
            raise holding_no_topic(bags)
        selection = resolve(selection, bags, names, inputs.spans, report)
        latched = latched_messages(
            bags, {n: t for f in files for n, t in f.known.items()}, selection
        )
        out = OutputBag.create(output, options)
        out.custom_data = merged_custom_data(inputs.custom_data)
        out.custom_data.update(rewrites.custom_data)
        try:
            _add_topics(files, out, selection, rewrites)
            if latched and selection.window.start_ns is not None:
                write_latched(out, latched, selection.window.start_ns)
            copy_files(files, out, selection, CopyOptions(options.check_crc, stored_order))
            report.files = out.commit()
        except BaseException:
            out.abort()
            raise
    for file in files:
        report.problems.extend(file.problems)
    report.problems += [f.problem for f in selection.content.values() if f.problem]
    report.input_messages = sum(f.index.message_count for f in files)
    report.topic_counts = {n: out.counts[c.id] for n, c in out.channels.items()}
    report.chunks_copied = out.chunks_copied
    report.latched_messages = len(latched)
    return report


@dataclass
class _Inputs:
    """What the inputs' readers told: each bag's (first, last) log time when it has messages,
    and each bag's (name, custom_data)."""

    spans: list[tuple[int, int]] = field(default_factory=list)
    custom_data: list[tuple[str, dict[str, str]]] = field(default_factory=list)


def check_output(bags: Sequence[Path], output: Path, options: OutputOptions) -> None:
    """Raise SurgeryError when ``output`` is, holds or is inside one of ``bags``, or names one
    MCAP file that ``options`` cannot be written to
    (:func:`~bagkit.surgery.output_paths.single_file`)."""
    single_file(output, options)
    target = output.resolve()
    for bag in bags:
        if not isinstance(bag, Path):  # a bag in storage (UrlPath): never under a local output
            continue
        source = bag.resolve()
        if target == source or target in source.parents or source in target.parents:
            raise SurgeryError(f"the output {output} would overlap the input {bag}")


class ScannedFiles:
    """The indexes of the MCAP files read so far in one rewrite, by the file's identity (device,
    inode, size, modification time): a file without a summary is scanned whole to index it,
    and the copyability check, the bag's reader and the copy would each scan it again."""

    def __init__(self) -> None:
        self._indexes: dict[tuple[int, int, int, int], FileIndex] = {}

    def add(self, mcap: McapFile) -> None:
        """Keep the index of ``mcap`` (opened, on disk)."""
        if isinstance(mcap.path, Path):  # a bag in storage (UrlPath) has no inode
            self._indexes[_identity(os.stat(mcap.path))] = mcap.index

    def index(self, path: Path, source: Source) -> FileIndex:
        """The index of ``source`` (``path``, opened): kept, or read now (a bag in storage's
        always: its handle reads by range, it has no file descriptor)."""
        known = None
        if isinstance(path, Path):
            known = self._indexes.get(_identity(os.fstat(source.f.fileno())))
        return known if known is not None else read_file_index(source)


def _identity(stat: os.stat_result) -> tuple[int, int, int, int]:
    return stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns


@contextlib.contextmanager
def _opened_inputs(
    bags: list[Path], report: RewriteReport, inputs: _Inputs, scanned: ScannedFiles
) -> Iterator[list[InputFile]]:
    """Every MCAP file of ``bags`` in order, with its index (summary or salvage: ``scanned``'s
    when it holds it); what each bag's reader tells is appended to ``inputs``."""
    files: list[InputFile] = []
    handles = []
    try:
        for bag in bags:
            with BagReader(bag, allow_empty=True) as reader:
                paths, known, missing = list(reader.files), dict(reader.topics), reader.problems
                for storage in reader.storage_files:
                    if isinstance(storage, McapFile):
                        scanned.add(storage)
                if reader.message_count:
                    inputs.spans.append((reader.start_ns, reader.end_ns))
                custom_data = dict(reader.metadata.custom_data) if reader.metadata else {}
                inputs.custom_data.append((bag.name, custom_data))
            report.problems.extend(p for p in missing if "missing" in p or "unreadable" in p)
            for path in paths:
                handle = path.open("rb")  # closed below; a UrlPath's is read by range
                handles.append(handle)
                if handle.read(len(MAGIC)) != MAGIC:
                    raise SurgeryError(f"{path}: only MCAP storage can be rewritten")
                source = Source(handle, path.name)
                index = scanned.index(path, source)
                files.append(InputFile(path, source, index, known, problems=list(index.problems)))
        yield files
    finally:
        for handle in handles:
            handle.close()


def chunks_copyable(bags: Sequence[Path], scanned: ScannedFiles | None = None) -> bool:
    """Whether the chunks of ``bags`` can be copied as stored: every storage file is MCAP, by
    its magic (a SQLite3 bag counts its rows on opening), of plain CDR payloads, not rosbag2's
    message-compressed ones (metadata.yaml says, else the file's own rosbag2 record). A path
    that is no file or directory, or bad metadata.yaml, is left to the reader to report. The
    files indexed to read their rosbag2 record are added to ``scanned``."""
    for bag in bags:
        folder = bag.parent if bag.name == METADATA_FILENAME else bag
        metadata = None
        if folder.is_dir():
            files = [f for f in folder.iterdir() if f.is_file() and f.suffix != ".yaml"]
            try:
                metadata = read_metadata(folder)
            except BagError:
                return False
        else:
            files = [bag] if bag.is_file() else []
        if metadata is not None and metadata.compression_mode == "message":
            return False
        for file in files:
            with file.open("rb") as f:
                if f.read(len(MAGIC)) != MAGIC:
                    return False
            if metadata is None and _zstd_payloads(file, scanned):
                return False
    return True


def _zstd_payloads(file: Path, scanned: ScannedFiles | None) -> bool:
    """Whether the MCAP ``file`` says (its rosbag2 record) it holds zstd-framed payloads."""
    mcap = McapFile(file)
    try:
        mcap.open()
        if scanned is not None:
            scanned.add(mcap)
        return message_compressed(mcap)
    except BagError:
        return False  # the reader reports it
    finally:
        mcap.close()


def _add_topics(
    files: list[InputFile], out: OutputBag, selection: Selection, rewrites: PayloadRewrites
) -> None:
    """Give the output every selected topic (input channel ids kept where possible); a
    rewritten topic as its rewrite lists it."""
    types: dict[str, str] = {}
    for file in files:
        for channel_id, topic, definition in topics_of(file.index, file.known):
            if not selection.topic_passes(topic.name):
                continue
            if topic.name in selection.content:
                file.content[channel_id] = selection.content[topic.name]
            known = types.setdefault(topic.name, topic.type)
            if known != topic.type:
                raise SurgeryError(
                    f"{topic.name} has type {known} in one input and {topic.type} in {file.path}"
                )
            rewrite = rewrites.topics.get(topic.name)
            if rewrite is not None:
                file.rewrites[channel_id] = rewrite
            written = (
                (topic, definition) if rewrite is None else (rewrite.topic, rewrite.definition)
            )
            file.channel_map[channel_id] = out.add_topic(*written, channel_id)
    if not out.channels:
        raise SurgeryError("no topic is selected")
