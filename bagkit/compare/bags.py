"""Comparing two bags: decode each topic from the bags' stored definitions, then the pure core."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.bag.definitions import canonical_type_name
from bagkit.compare.core import Event, Sample, compare_events, compare_samples
from bagkit.compare.errors import CompareError
from bagkit.compare.options import CompareOptions
from bagkit.compare.result import CompareReport, Divergence, TopicResult
from bagkit.decode import MessageTypes, flatten_message
from bagkit.errors import BagkitError

EVENT_TYPE = "diagnostic_msgs/msg/DiagnosticArray"


def iter_samples(bag: BagReader, topic: str, types: MessageTypes) -> Iterator[Sample]:
    """Every message of ``topic`` in ``bag`` as a Sample (flattened leaf fields).

    Raises:
        CompareError: the topic's messages cannot be decoded.
    """
    type_name = bag.topics[topic].type
    try:
        for msg in bag.messages(topics=[topic]):
            decoded = types.deserialize(msg.data, type_name)
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
    its messages missing or extra); otherwise the topics both bags have, and the topics only
    one of them has are listed as warnings.

    ``check_crc``: check each chunk's CRC as it is read (see ``BagReader``).

    Raises:
        CompareError: a bag cannot be read or decoded, or a requested topic is in neither bag.
    """
    options = options or CompareOptions()
    with ExitStack() as stack:
        try:
            g_bag = stack.enter_context(BagReader(golden, check_crc=check_crc))
            c_bag = stack.enter_context(BagReader(candidate, check_crc=check_crc))
        except BagkitError as exc:
            raise CompareError(str(exc)) from exc
        g_types = MessageTypes.from_definitions(g_bag.definitions)
        c_types = MessageTypes.from_definitions(c_bag.definitions)
        warnings: list[str] = []
        if options.topics is not None:
            unknown = [t for t in options.topics if t not in g_bag.topics and t not in c_bag.topics]
            if unknown:
                raise CompareError(f"topic(s) in neither bag: {', '.join(unknown)}")
            topics = list(options.topics)
        else:
            topics = sorted(g_bag.topics.keys() & c_bag.topics.keys())
            only_golden = sorted(g_bag.topics.keys() - c_bag.topics.keys())
            only_candidate = sorted(c_bag.topics.keys() - g_bag.topics.keys())
            if only_golden:
                warnings.append(f"not compared, only in the golden: {', '.join(only_golden)}")
            if only_candidate:
                warnings.append(f"not compared, only in the candidate: {', '.join(only_candidate)}")
            if not topics:
                raise CompareError("the bags have no topic in common")
        results: list[TopicResult] = []
        for topic in topics:
            if progress is not None:
                progress(topic)
            g_info, c_info = g_bag.topics.get(topic), c_bag.topics.get(topic)
            info = g_info or c_info
            assert info is not None
            if (
                g_info
                and c_info
                and canonical_type_name(g_info.type) != canonical_type_name(c_info.type)
            ):
                result = TopicResult(topic, canonical_type_name(g_info.type), "")
                result.divergence_count = result.shape_divergences = 1
                result.divergences = [Divergence("type", topic, 0, "", g_info.type, c_info.type)]
                results.append(result)
                continue
            try:
                g_samples = list(iter_samples(g_bag, topic, g_types)) if g_info else []
                c_samples = list(iter_samples(c_bag, topic, c_types)) if c_info else []
            except CompareError as exc:
                warnings.append(f"{exc}; compared byte for byte")
                g_samples = _raw_samples(g_bag, topic) if g_info else []
                c_samples = _raw_samples(c_bag, topic) if c_info else []
            if options.skip_ns:
                # Warm-up skipped on both sides by message time (stamp, else receive time).
                begin = g_bag.start_ns + options.skip_ns
                g_samples = [x for x in g_samples if x.time_ns >= begin]
                c_samples = [x for x in c_samples if x.time_ns >= begin]
            msg_type = canonical_type_name(info.type)
            if topic in options.event_topics and msg_type == EVENT_TYPE:
                result = compare_events(
                    topic, msg_type, events_of(g_samples), events_of(c_samples), options
                )
            else:
                result = compare_samples(topic, msg_type, g_samples, c_samples, options)
            results.append(result)
        warnings.extend([*g_bag.problems, *c_bag.problems])  # damaged chunks: messages lost
    return CompareReport(str(golden), str(candidate), results, warnings)
