"""``bagkit doctor``: check a bag the way ``mcap doctor`` checks a file, for whole rosbag2 bags.

Per MCAP file (:mod:`~bagkit.surgery.file_check`): CRCs, indexes against records, summary
against content, time order; per SQLite3 or compressed file
(:mod:`~bagkit.surgery.storage_check`): SQLite3's integrity check and what the back-end
reports. Per bag: metadata.yaml against the files (file list, counts,
times, topics), every schema decodable (:class:`bagkit.decode.MessageTypes`) and, with
``deep``, every message.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from bagkit.bag import safe_json
from bagkit.bag.definitions import DEFINITION_ENCODINGS, canonical_type_name
from bagkit.bag.distro_definitions import distro_definitions
from bagkit.bag.errors import BagError, BagNotFoundError, NotABagError
from bagkit.bag.mcapio import MAGIC, Source, read_file_index
from bagkit.bag.mcapio.records import Schema
from bagkit.bag.metadata import METADATA_FILENAME, BagMetadata, read_metadata
from bagkit.bag.storage_files import is_storage_name
from bagkit.decode import DecodeError, MessageTypes, SchemaError
from bagkit.recording.loss_causes import large_message_cause
from bagkit.recording.report import LOSS_CUSTOM_DATA_KEY
from bagkit.surgery.file_check import FileCheck, FileFacts, MessageCheck
from bagkit.surgery.storage_check import check_storage_file
from bagkit.words import counted


@dataclass(frozen=True)
class Finding:
    """One problem (or, ``note``, a fact about valid data): where (a file, the bag) and what."""

    where: str
    problem: str
    note: bool = False

    @property
    def line(self) -> str:
        """``where: problem`` (``note: where: ...`` for a note)."""
        return f"{'note: ' if self.note else ''}{self.where}: {self.problem}"


@dataclass
class DoctorReport:
    """What ``doctor`` checked and found."""

    path: Path
    files: list[str] = field(default_factory=list)
    message_count: int = 0
    deep: bool = False
    findings: list[Finding] = field(default_factory=list)
    undecoded: dict[str, str] = field(default_factory=dict)
    """Topics whose type has no stored definition and none in the type stores: why."""

    @property
    def healthy(self) -> bool:
        """No problem found (notes aside)."""
        return not any(not f.note for f in self.findings)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return {
            "path": str(self.path),
            "files": self.files,
            "message_count": self.message_count,
            "deep": self.deep,
            "healthy": self.healthy,
            "problems": [
                {"where": f.where, "problem": f.problem} for f in self.findings if not f.note
            ],
            "notes": [{"where": f.where, "note": f.problem} for f in self.findings if f.note],
        }


def diagnose(path: Path, *, deep: bool = False) -> DoctorReport:
    """Check the bag at ``path`` (a bag directory, its metadata.yaml, or one ``.mcap`` file).

    Raises:
        BagNotFoundError: no such path.
        NotABagError: no storage file could be opened at all.
    """
    bag_dir, files = _storage_files(path)
    report = DoctorReport(path=path, deep=deep)
    metadata = _metadata(bag_dir, path, report)
    facts: dict[str, FileFacts] = {}
    decoders = _Decoders(deep, metadata.ros_distro if metadata is not None else "")
    compression_mode = metadata.compression_mode if metadata is not None else None
    for file in files:
        checked = _check_file(file, decoders, report, compression_mode)
        if checked is not None:
            facts[file.name] = checked
            report.files.append(file.name)
    if not facts:
        first = report.findings[-1].line if report.findings else "none found"
        raise NotABagError(f"{path}: no readable storage file ({first})")
    report.message_count = sum(f.message_count for f in facts.values())
    if metadata is not None:
        report.findings.extend(
            Finding(METADATA_FILENAME, p) for p in _metadata_problems(metadata, facts, bag_dir)
        )
    report.findings.extend(Finding("bag", p) for p in decoders.problems())
    report.undecoded = decoders.undecoded()
    report.findings.extend(
        Finding("bag", f"{topic}: not decoded ({why})", note=True)
        for topic, why in report.undecoded.items()
    )
    if metadata is not None:
        report.findings.extend(Finding("bag", n, note=True) for n in _loss_causes(metadata))
    return report


def _loss_causes(metadata: BagMetadata) -> list[str]:
    """Why the recorder lost messages, from its counts in custom_data (bagkit record's)."""
    try:
        loss = safe_json.loads(metadata.custom_data.get(LOSS_CUSTOM_DATA_KEY, "{}"))
        causes = [
            large_message_cause(
                topic, int(c.get("gaps", 0)), int(c.get("messages", 0)), int(c.get("bytes", 0))
            )
            for topic, c in loss.items()
        ]
    except (ValueError, TypeError, AttributeError):
        return ["the recorder's loss counts (custom_data bagkit.record.loss) are not readable"]
    return [cause for cause in causes if cause is not None]


def _storage_files(path: Path) -> tuple[Path | None, list[Path]]:
    if not path.exists():
        raise BagNotFoundError(f"{path}: no such file or directory")
    if path.is_file() and path.name == METADATA_FILENAME:
        path = path.parent
    if path.is_file():
        return None, [path]
    files = sorted(p for p in path.iterdir() if is_storage_name(p.name) and p.is_file())
    if not files:
        raise NotABagError(f"{path}: no storage file (.mcap, .db3, .mcap.zstd, .db3.zstd)")
    return path, files


def _metadata(bag_dir: Path | None, path: Path, report: DoctorReport) -> BagMetadata | None:
    if bag_dir is None:
        return None
    try:
        metadata = read_metadata(bag_dir)
    except NotABagError as exc:
        text = str(exc).removeprefix(f"{bag_dir / METADATA_FILENAME}: ")
        report.findings.append(Finding(METADATA_FILENAME, " ".join(text.split())))  # one line
        return None
    if metadata is None:
        report.findings.append(
            Finding("bag", f"no {METADATA_FILENAME} (`bagkit recover` writes one)")
        )
    return metadata


class _Decoders:
    """Schemas of all files, and (deep) a decode of every message."""

    def __init__(self, deep: bool, ros_distro: str) -> None:
        self.deep = deep
        self.ros_distro = ros_distro  # what metadata.yaml names: the types of textless schemas
        # Per schema (type name, text): two schemas of one type name each decode with their own.
        self.types: dict[tuple[str, str], MessageTypes] = {}
        self.type_of: dict[str, tuple[str, str]] = {}  # topic -> its schema
        self.failures: dict[str, tuple[int, int, str]] = {}  # topic -> (count, first time, why)
        self._textless: set[tuple[str, str]] = set()  # schemas without a usable text
        # The distribution's definitions of textless schemas' types, by type (those asked).
        self._assumed: dict[str, str] = {}
        self._asked: set[str] = set()

    def for_file(self, facts: FileFacts) -> Callable[[int, int, memoryview], None] | None:
        """The per-message check of one file (None unless deep)."""
        if not self.deep:
            return None
        cache: dict[int, tuple[str, Callable[[bytes | memoryview], object] | None]] = {}

        def check(channel_id: int, log_time: int, payload: memoryview) -> None:
            if channel_id not in cache:
                cache[channel_id] = self._decoder(facts, channel_id)
            topic, decode = cache[channel_id]
            if decode is None:
                return
            try:
                decode(payload)
            except DecodeError as exc:
                count, first, why = self.failures.get(topic, (0, log_time, str(exc)))
                self.failures[topic] = (count + 1, first, why)

        return check

    def _decoder(
        self, facts: FileFacts, channel_id: int
    ) -> tuple[str, Callable[[bytes | memoryview], object] | None]:
        channel = facts.channels.get(channel_id)
        if channel is None:
            return f"channel {channel_id}", None
        schema = facts.schemas.get(channel.schema_id)
        if schema is None:
            return channel.topic, None
        try:
            return channel.topic, self._types(schema).decoder(schema.name)
        except SchemaError:
            return channel.topic, None

    def add_schemas(self, facts: FileFacts) -> None:
        schemas = {
            channel.topic: schema
            for channel in facts.channels.values()
            if (schema := facts.schemas.get(channel.schema_id)) is not None
        }
        self._assume(s.name for s in schemas.values() if s.encoding not in DEFINITION_ENCODINGS)
        for topic, schema in schemas.items():
            self._types(schema)
            self.type_of[topic] = _key(schema)

    def _assume(self, type_names: Iterable[str]) -> None:
        """Ask the bag's distribution for the definitions of ``type_names`` not asked yet, all
        at once: one warning names every type assumed."""
        wanted = set(type_names) - self._asked
        if wanted:
            self._assumed.update(distro_definitions(wanted, self.ros_distro))
            self._asked |= wanted

    def _types(self, schema: Schema) -> MessageTypes:
        key = _key(schema)
        if key not in self.types:
            # A schema without a usable text (rosbag2's ``unknown``, a .db3 without the type's
            # definition): the type as the read commands take it (the bag's distribution's).
            stored = schema.encoding in DEFINITION_ENCODINGS
            if stored:
                definitions = {key[0]: key[1]}
            else:
                self._assume([key[0]])
                definitions = {key[0]: self._assumed[key[0]]} if key[0] in self._assumed else {}
                self._textless.add(key)
            self.types[key] = MessageTypes.from_definitions(definitions)
        return self.types[key]

    def problems(self) -> list[str]:
        found = []
        for topic, key in sorted(self.type_of.items()):
            if key not in self._textless:
                try:
                    self.types[key].resolve(key[0])
                except SchemaError as exc:
                    found.append(f"{topic}: {exc}")
        for topic, (count, first, why) in sorted(self.failures.items()):
            found.append(
                f"{topic}: {counted(count, 'message')} did not decode (first at log time "
                f"{first}: {why})"
            )
        return found

    def undecoded(self) -> dict[str, str]:
        """Topics without a stored text whose type no type store has either: not a damage
        (Foxy to Humble bags store no definitions), but nothing of them could be checked."""
        found = {}
        for topic, key in sorted(self.type_of.items()):
            if key in self._textless:
                try:
                    self.types[key].resolve(key[0])
                except SchemaError as exc:
                    found[topic] = str(exc)
        return found


def _key(schema: Schema) -> tuple[str, str]:
    return schema.name, schema.data.decode("utf-8", errors="replace")


def _check_file(
    file: Path, decoders: _Decoders, report: DoctorReport, compression_mode: str | None
) -> FileFacts | None:
    try:
        with open(file, "rb") as handle:
            # Compressed payloads are read through the compression layer.
            if handle.read(len(MAGIC)) != MAGIC or compression_mode == "message":
                return _check_storage_file(file, decoders, report, compression_mode)
            source = Source(handle, file.name)
            # Schemas and channels first (from a shallow walk) so that deep checks can decode.
            check = FileCheck(source)
            pre = _prescan(source) if decoders.deep else None
            if pre is not None:
                decoders.add_schemas(pre)
                check.check_message = decoders.for_file(pre)
            facts = check.run()
    except (BagError, OSError) as exc:
        report.findings.append(Finding(file.name, f"unreadable ({exc})"))
        return None
    decoders.add_schemas(facts)
    report.findings.extend(Finding(file.name, p) for p in facts.problems)
    report.findings.extend(Finding(file.name, n, note=True) for n in facts.notes)
    return facts


def _check_storage_file(
    file: Path, decoders: _Decoders, report: DoctorReport, compression_mode: str | None
) -> FileFacts | None:
    """A SQLite3 or compressed file, through the bag back-ends."""

    def check_for(facts: FileFacts) -> MessageCheck | None:
        decoders.add_schemas(facts)
        return decoders.for_file(facts)

    try:
        facts = check_storage_file(file, compression_mode, check_for)
    except (BagError, OSError) as exc:
        report.findings.append(Finding(file.name, f"unreadable ({exc})"))
        return None
    decoders.add_schemas(facts)
    report.findings.extend(Finding(file.name, p) for p in facts.problems)
    return facts


def _prescan(source: Source) -> FileFacts:
    """Schemas and channels of a file, from its summary or a scan (for decoding while walking)."""
    index = read_file_index(source)
    return FileFacts(schemas=dict(index.schemas), channels=dict(index.channels))


def _metadata_problems(
    metadata: BagMetadata, facts: dict[str, FileFacts], bag_dir: Path | None
) -> list[str]:
    problems = []
    listed = [Path(p).name for p in metadata.relative_file_paths]
    for name in dict.fromkeys(listed):
        if listed.count(name) > 1:
            problems.append(f"lists {name} {counted(listed.count(name), 'time')}")
        if name not in facts:
            problems.append(f"lists {name}, which is missing or unreadable")
    for name in facts:
        if name not in listed:
            problems.append(f"does not list {name}")
    total = sum(f.message_count for f in facts.values())
    if metadata.message_count != total:
        problems.append(f"message_count is {metadata.message_count}, the files hold {total}")
    problems.extend(_topic_problems(metadata, facts))
    problems.extend(_time_problems(metadata, facts))
    for entry in metadata.files:
        found = facts.get(Path(entry.path).name)
        if found is not None and entry.message_count != found.message_count:
            problems.append(
                f"files: {entry.path} has message_count {entry.message_count}, "
                f"the file holds {found.message_count}"
            )
    return problems


def _topic_problems(metadata: BagMetadata, facts: dict[str, FileFacts]) -> list[str]:
    counts: dict[str, int] = {}
    types: dict[str, str] = {}
    for file in facts.values():
        for channel in file.channels.values():
            counts.setdefault(channel.topic, 0)
            schema = file.schemas.get(channel.schema_id)
            if schema is not None:
                types[channel.topic] = canonical_type_name(schema.name)
        for channel_id, count in file.counts.items():
            holder = file.channels.get(channel_id)
            if holder is not None:
                counts[holder.topic] = counts.get(holder.topic, 0) + count
    problems = []
    recorded = {topic.name: (topic, count) for topic, count in metadata.topics}
    for name, (topic, count) in sorted(recorded.items()):
        if name not in counts:
            if count:
                problems.append(f"{name}: message_count is {count}, no file holds the topic")
            continue
        if count != counts[name]:
            problems.append(f"{name}: message_count is {count}, the files hold {counts[name]}")
        if name in types and canonical_type_name(topic.type) != types[name]:
            problems.append(f"{name}: type is {topic.type}, the files store {types[name]}")
    for name in sorted(counts.keys() - recorded.keys()):
        problems.append(f"does not list topic {name}")
    return problems


def _time_problems(metadata: BagMetadata, facts: dict[str, FileFacts]) -> list[str]:
    starts = [f.start for f in facts.values() if f.start is not None]
    if not starts:
        return []
    start, end = min(starts), max(f.end for f in facts.values() if f.start is not None)
    problems = []
    if metadata.starting_time != start:
        problems.append(
            f"starting_time is {metadata.starting_time}, the first message is at {start}"
        )
    if metadata.duration != end - start:
        problems.append(f"duration is {metadata.duration} ns, the messages span {end - start} ns")
    return problems
