"""Comparing two bags: decode each topic from the bags' stored definitions, then the pure core."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.bag.definitions import canonical_type_name
from bagkit.compare.core import Event, Sample, compare_events, compare_samples
from bagkit.compare.errors import CompareError
from bagkit.compare.options import CompareOptions
from bagkit.compare.result import CompareReport, Divergence, TopicResult
from bagkit.decode import DecodeError, MessageTypes, flatten_message, leaf_fields
from bagkit.errors import BagkitError
from bagkit.selection.errors import UnknownFieldError
from bagkit.selection.fields import name_matches, path_matches, split_pattern, unknown_field_message
from bagkit.selection.topics import did_you_mean, require_topics
from bagkit.words import counted

EVENT_TYPE = "diagnostic_msgs/msg/DiagnosticArray"


def iter_samples(
    bag: BagReader, topic: str, types: MessageTypes, *, undecodable: list[str] | None = None
) -> Iterator[Sample]:
    """Every message of ``topic`` in ``bag`` as a Sample (flattened leaf fields).

    Args:
        undecodable: when given, a message whose payload does not decode is left out and why
            is appended here; otherwise it raises like a type that cannot be decoded.

    Raises:
        CompareError: the topic's type (or, without ``undecodable``, a message) cannot be
            decoded.
    """
    type_name = bag.topics[topic].type
    types = types.for_topic(topic)
    try:
        decode = types.decoder(type_name)
        for msg in bag.messages(topics=[topic]):
            try:
                decoded = decode(msg.data)
            except DecodeError as exc:
                if undecodable is None:
                    raise
                undecodable.append(str(exc))
                continue
            fields = flatten_message(decoded, types.typestore)
            yield Sample(msg.log_time, msg.publish_time, fields)
    except BagkitError as exc:
        raise CompareError(f"{topic}: {exc}") from exc


def _raw_samples(bag: BagReader, topic: str) -> list[Sample]:
    """Messages that cannot be decoded, as their serialized bytes (field ``~cdr``)."""
    return [Sample(m.log_time, m.publish_time, {"~cdr": m.data}) for m in bag.messages([topic])]


def events_of(samples: list[Sample]) -> list[Event]:
    """The statuses of DiagnosticArray samples as events at the array's header stamp."""
    events: list[Event] = []
    for sample in samples:
        names = list(sample.fields.get("status[].name", []))
        levels = sample.fields.get("status[].level", [])
        level_list = list(levels.tolist() if hasattr(levels, "tolist") else levels)
        messages = list(sample.fields.get("status[].message", []))
        for name, level, text in zip(names, level_list, messages, strict=True):
            events.append(Event(sample.time_ns, str(name), int(level), str(text)))
    return events


def field_series(
    bag: BagReader, topic: str, path: str, types: MessageTypes
) -> tuple[list[float], list[float]]:
    """Times (s, header stamp or receive time) and values of one numeric scalar field."""
    times: list[float] = []
    values: list[float] = []
    for sample in iter_samples(bag, topic, types):
        value = sample.fields.get(path)
        if isinstance(value, int | float) and not isinstance(value, bool):
            times.append(sample.time_ns / 1e9)
            values.append(float(value))
    return times, values


@dataclass(slots=True)
class _Side:
    """One of the two bags being compared, with its decoder."""

    bag: BagReader
    types: MessageTypes

    def samples(self, topic: str, undecodable: list[str]) -> list[Sample]:
        """The decoded messages of ``topic``; why the others did not decode in ``undecodable``.

        Raises:
            CompareError: the type cannot be decoded, or none of its messages decodes (the
                definition does not describe them).
        """
        if topic not in self.bag.topics:
            return []
        samples = list(iter_samples(self.bag, topic, self.types, undecodable=undecodable))
        if undecodable and not samples:
            raise CompareError(f"{topic}: no message decodes ({undecodable[0]})")
        return samples

    def raw_samples(self, topic: str) -> list[Sample]:
        return _raw_samples(self.bag, topic) if topic in self.bag.topics else []


def compare_bags(
    golden: Path,
    candidate: Path,
    options: CompareOptions | None = None,
    *,
    progress: Callable[[str], None] | None = None,
    check_crc: bool = True,
) -> CompareReport:
    """Compare ``candidate`` with ``golden`` topic by topic.

    Topics: ``options.topics`` when set (a topic missing from either bag then fails with all
    its messages missing or extra); otherwise the topics of the golden (one the candidate
    lacks fails: :attr:`TopicResult.absent`), and the topics only the candidate has are
    listed as warnings. A golden topic with messages of which the candidate has none fails
    whatever the pass rate. A message that does not decode is left out and
    counted (``golden_undecodable``/``candidate_undecodable``, a failed message each, and a
    warning); a topic whose type cannot be decoded, or none of whose messages decodes, is
    compared byte for byte.

    ``check_crc``: check each chunk's CRC as it is read (see ``BagReader``).

    Raises:
        CompareError: a bag cannot be read, or a requested topic is in neither bag.
    """
    options = options or CompareOptions()
    with ExitStack() as stack:
        try:
            g_bag = stack.enter_context(BagReader(golden, check_crc=check_crc))
            c_bag = stack.enter_context(BagReader(candidate, check_crc=check_crc))
        except BagkitError as exc:
            raise CompareError(str(exc)) from exc
        golden_side = _Side(g_bag, MessageTypes.for_bag(g_bag))
        candidate_side = _Side(c_bag, MessageTypes.for_bag(c_bag))
        warnings: list[str] = []
        results: list[TopicResult] = []
        _check_ignored(options, golden_side, candidate_side)
        for topic in _topics(g_bag, c_bag, options, warnings):
            if progress is not None:
                progress(topic)
            results.append(_compare_topic(topic, golden_side, candidate_side, options, warnings))
        warnings.extend([*g_bag.problems, *c_bag.problems])  # damaged chunks: messages lost
    return CompareReport(str(golden), str(candidate), results, warnings)


def _check_ignored(options: CompareOptions, *sides: _Side) -> None:
    """Every ``ignore_fields`` pattern selects a field of the bags: a misspelt one would
    silently compare what the user meant to leave out.

    A topic glob with wildcards that matches no topic is left alone (a spec may be shared by
    fixtures with other topics); a named topic must be in a bag.

    Raises:
        UnknownTopicError, UnknownFieldError: with the closest names the bags have.
    """
    types = {name: (side, info.type) for side in sides for name, info in side.bag.topics.items()}
    for pattern in options.ignore_fields:
        topic_glob, field_glob = split_pattern(pattern)
        if not any(c in topic_glob for c in "*?"):
            require_topics([topic_glob], types, "either bag")
        topics = [name for name in sorted(types) if name_matches(name, topic_glob)]
        paths = ["~log_time", "~publish_time"]
        for name in topics:
            side, type_name = types[name]
            try:
                leaves = leaf_fields(side.types.typestore, side.types.resolve(type_name))
            except DecodeError:
                return  # compared byte for byte: any field may be meant
            paths.extend(leaf.path for leaf in leaves)
        if not topics or any(path_matches(path, field_glob) for path in paths):
            continue
        if len(topics) == 1:
            raise UnknownFieldError(unknown_field_message(topics[0], [field_glob], paths[2:]))
        guess = did_you_mean(field_glob, paths).rstrip() or f"{counted(len(topics), 'topic')} match"
        raise UnknownFieldError(
            f"no topic matching {topic_glob} has the field {field_glob} ({guess})"
        )


def _topics(
    g_bag: BagReader, c_bag: BagReader, options: CompareOptions, warnings: list[str]
) -> list[str]:
    """The topics to compare (see :func:`compare_bags`)."""
    if options.topics is not None:
        return require_topics(
            options.topics, g_bag.topics.keys() | c_bag.topics.keys(), "either bag"
        )
    topics = sorted(g_bag.topics.keys() & c_bag.topics.keys())
    only_candidate = sorted(c_bag.topics.keys() - g_bag.topics.keys())
    if only_candidate:
        warnings.append(f"not compared, only in the candidate: {', '.join(only_candidate)}")
    if not topics:
        raise CompareError("the bags have no topic in common")
    return sorted(g_bag.topics)


def _compare_topic(
    topic: str, golden: _Side, candidate: _Side, options: CompareOptions, warnings: list[str]
) -> TopicResult:
    g_info, c_info = golden.bag.topics.get(topic), candidate.bag.topics.get(topic)
    info = g_info or c_info
    assert info is not None
    if g_info and c_info and canonical_type_name(g_info.type) != canonical_type_name(c_info.type):
        result = TopicResult(topic, canonical_type_name(g_info.type), "")
        result.divergence_count = result.shape_divergences = 1
        result.divergences = [Divergence("type", topic, 0, "", g_info.type, c_info.type)]
        return result
    g_bad: list[str] = []
    c_bad: list[str] = []
    try:
        g_samples = golden.samples(topic, g_bad)
        c_samples = candidate.samples(topic, c_bad)
    except CompareError as exc:
        warnings.append(f"{exc}; compared byte for byte")
        g_samples, c_samples = golden.raw_samples(topic), candidate.raw_samples(topic)
        g_bad.clear()
        c_bad.clear()
    if g_bad or c_bad:
        warnings.append(
            f"{topic}: {counted(len(g_bad), 'golden message')} and "
            f"{counted(len(c_bad), 'candidate message')} could not be decoded and are left out "
            f"({(g_bad or c_bad)[0]})"
        )
    if options.skip_ns:
        # Warm-up skipped on both sides by message time (stamp, else receive time).
        begin = golden.bag.start_ns + options.skip_ns
        g_samples = [x for x in g_samples if x.time_ns >= begin]
        c_samples = [x for x in c_samples if x.time_ns >= begin]
    msg_type = canonical_type_name(info.type)
    if topic in options.event_topics and msg_type == EVENT_TYPE:
        result = compare_events(
            topic, msg_type, events_of(g_samples), events_of(c_samples), options
        )
    else:
        result = compare_samples(topic, msg_type, g_samples, c_samples, options)
    result.golden_undecodable, result.candidate_undecodable = len(g_bad), len(c_bad)
    if g_info is not None and c_info is None:
        result.absent = "not in the candidate"
    elif g_info is not None and result.golden_count and not result.candidate_count:
        result.absent = "no message in the candidate"
    # A message that cannot be checked is not a message that passed.
    result.failed_messages += len(g_bad) + len(c_bad)
    return result
