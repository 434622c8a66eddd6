"""``bagkit info``: what a bag holds, like ``ros2 bag info``, from summaries and indexes only."""

from __future__ import annotations

import datetime
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import typer
import yaml

from bagkit.bag import BagInfo, bag_info, safe_json, safe_yaml
from bagkit.bag.action_info import ActionSummary, action_summaries
from bagkit.bag.compression_words import CompressionWords
from bagkit.cli import common
from bagkit.cli.common import ReportFormat, fail, format_rate, handle_errors, print_json, warn
from bagkit.cli.option_parsing import BAG_HELP
from bagkit.cli.selection_options import Distro
from bagkit.cli.tables import (
    INDENT,
    Column,
    Styled,
    Table,
    print_fields,
    print_line,
    print_table,
    print_wrapped,
)
from bagkit.storage.urls import is_url
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.data.service_summaries import ServiceSummary
    from bagkit.fleet.listing import FolderInfo

HELP = """Show what a bag holds: files, size, storage, duration, start and end, message count,
and per topic its type, count, rate, serialization format and offered QoS.

BAG is a bag directory (split or not, with or without metadata.yaml), a single .mcap or .db3
file (or rosbag2's .zstd of one), a ROS 1 .bag file, or a URL of one. Only summaries and
indexes are read, so this is instant on multi-GB bags; a crashed recording without a summary
is salvaged and what could not be read is reported.
A folder of bags (a snapshot-mode output, a fleet folder) lists its bags, one line each, and
their totals (one that cannot be read is a warning, and exit status 2). A topic's rate is
(count - 1) / (last - first log time), "-" below three messages or one second. A bag in
storage (a URL) is read by range requests of its summary only: each topic's first and last
time are then bounded by the chunks that hold them, and its rate, a lower bound, is marked
"~" (--exact-rates reads the message indexes too).
Services recorded from their introspection events (NAME/_service_event) are listed with their
event, request and response counts and their latency (median, 99th percentile, maximum).
Actions (NAME/_action/feedback and NAME/_action/status) are listed with the message counts of
their parts.

Example:

  bagkit info my_bag -v
"""

# rosbag2 metadata versions < 9 store QoS policies as rmw enum integers.
_POLICY_NAMES = {
    "history": {0: "system_default", 1: "keep_last", 2: "keep_all", 3: "unknown"},
    "reliability": {0: "system_default", 1: "reliable", 2: "best_effort", 3: "unknown"},
    "durability": {0: "system_default", 1: "transient_local", 2: "volatile", 3: "unknown"},
}


def _qos_summary(offered: str) -> str:
    """One line per offered profile: ``reliable, volatile, keep_last(10)``."""
    try:
        # Channel metadata is untrusted: limits on depth and size, no aliases.
        profiles = safe_yaml.load(offered) if offered else []
    except yaml.YAMLError:
        return "unparsable"
    if not isinstance(profiles, list):
        return "unparsable"
    lines = []
    for profile in profiles:
        if not isinstance(profile, dict):
            continue
        names = {
            key: _POLICY_NAMES[key].get(value, str(value)) if isinstance(value, int) else value
            for key, value in profile.items()
            if key in _POLICY_NAMES
        }
        policies = [str(names.get("reliability", "?")), str(names.get("durability", "?"))]
        history = names.get("history")
        if history == "keep_last":
            policies.append(f"keep_last({profile.get('depth', '?')})")
        elif history == "keep_all":
            policies.append("keep_all")
        lines.append(", ".join(policies))
    unique = list(dict.fromkeys(lines))
    return "\n".join(unique) if unique else "-"


def _size(n: int) -> str:
    value = float(n)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if value < 1024 or unit == "GiB":
            return f"{value:.1f} {unit}" if unit != "B" else f"{n} B"
        value /= 1024
    raise AssertionError("unreachable")


def _time(ns: int) -> str:
    stamp = datetime.datetime.fromtimestamp(ns // 1_000_000_000, tz=datetime.timezone.utc)
    seconds, fraction = divmod(ns, 1_000_000_000)
    return f"{stamp:%b %d %Y %H:%M:%S}.{fraction:09d} UTC ({seconds}.{fraction:09d})"


def _custom_data_value(value: str, verbose: bool) -> str:
    """A custom_data value for the table: a long JSON document is summarized unless -v."""
    if verbose or len(value) <= 60:
        return value
    try:
        document = safe_json.loads(value)
    except ValueError:
        return value
    if isinstance(document, dict):
        entries = counted(len(document), "entry", "entries")
        return f"JSON, {entries} (-v or --format json to see them)"
    return value


def _services(bag: str, result: BagInfo) -> list[ServiceSummary]:
    """The bag's services; their events are read (headers only) only if it has any."""
    from bagkit.selection.services import is_service_event_topic

    if not any(is_service_event_topic(t.topic, [t.type]) for t in result.topics):
        return []
    from bagkit.data.service_summaries import service_summaries

    return service_summaries(bag)


def _print_services(services: list[ServiceSummary]) -> None:
    table = Table(
        [
            Column("Service", style="cyan"),
            Column("Type"),
            Column("Events", numeric=True),
            Column("Requests", numeric=True),
            Column("Responses", numeric=True),
            Column("Latency p50/p99/max", numeric=True),
        ],
        "Services",
    )
    for service in services:
        latency = service.latency
        values = (latency.p50_ns, latency.p99_ns, latency.max_ns)
        timing = "/".join(f"{v / 1e6:.3g}" for v in values if v is not None)
        timing = f"{timing} ms" if timing else "-"
        counts = service.counts
        table.add_row(
            service.service,
            service.type,
            f"{counts.events:,}",
            f"{counts.requests:,}",
            f"{counts.responses:,}",
            timing,
        )
    print_table(table)


def _print_actions(actions: list[ActionSummary]) -> None:
    table = Table(
        [
            Column("Action", style="cyan"),
            Column("Type"),
            Column("Feedback", numeric=True),
            Column("Status", numeric=True),
            Column("Service events", numeric=True),
        ],
        "Actions",
    )
    for action in actions:
        table.add_row(
            action.action,
            action.type or "-",
            f"{action.feedback:,}",
            f"{action.status:,}",
            f"{action.service_events:,}",
        )
    print_table(table)


def _compression_rows(info: BagInfo) -> list[tuple[str, str]]:
    """``Compression``: rosbag2's (``zstd, file mode``), or else the chunks'; then the chunks'
    apart (``Chunk compression``) when rosbag2 compressed an MCAP or ROS 1 file as well."""
    words = CompressionWords.of(info.compression_mode, info.chunk_compression)
    ratio = f" (ratio {info.compression_ratio:.2f})"
    if not words.rosbag2:
        chunks = words.chunks
        return [("Compression", chunks + ratio if chunks and chunks != "none" else "none")]
    rows = [("Compression", words.rosbag2 + (ratio if info.compression_mode == "file" else ""))]
    return [*rows, ("Chunk compression", words.chunks)] if words.chunks else rows


def _print_table(info: BagInfo, verbose: bool) -> None:
    directory = Path(info.path) if Path(info.path).is_dir() else None
    files = [str(Path(f).relative_to(directory)) if directory else f for f in info.files]
    rows = [
        ("Files", "\n".join(files)),
        ("Bag size", _size(info.size_bytes)),
        ("Storage id", info.storage),
        ("Duration", f"{info.duration_s:.9f}s"),
        # No message, no time: a bag's 0 would show as 1970 (rosbag2's as 2262).
        ("Start", _time(info.start_ns) if info.message_count else "-"),
        ("End", _time(info.end_ns) if info.message_count else "-"),
        ("Messages", f"{info.message_count:,}"),
        *_compression_rows(info),
    ]
    if not info.summary:
        rows.append(("Summary", "missing: the recording did not finish, salvaged"))
    print_fields(rows, names=frozenset({"Files"}))
    if info.custom_data:  # keys of their own width: a long one would push every value right
        print_line([Styled("custom_data", "bold")])
        print_fields(
            [
                (f"  {key}", _custom_data_value(value, verbose))
                for key, value in info.custom_data.items()
            ]
        )
    columns = [Column("Topic", style="cyan"), Column("Type")]
    topics = Table(
        [*columns, Column("Count", numeric=True), Column("Rate", numeric=True)], "Topics"
    )
    about = "" if info.exact_rates else "~"
    for topic in info.topics:
        rate = format_rate(topic.rate_hz)
        topics.add_row(topic.topic, topic.type, f"{topic.count:,}", about + rate)
    print_table(topics)
    if about and any(t.rate_hz is not None for t in info.topics):
        note = "~ rates over the chunks that hold each topic (lower bounds; --exact-rates"
        print_wrapped([*note.split(" "), "reads", "the", "message", "indexes)"])
    if verbose:
        # One line per topic (and offered profile) rather than two more columns: at 80
        # columns those would not leave room for the names.
        print_line([Styled("Serialization and offered QoS:", "bold")])
        for topic in info.topics:
            qos = _qos_summary(topic.offered_qos_profiles).replace("\n", "; ")
            line = f"{topic.topic}: {topic.serialization_format}, {qos}"
            print_wrapped(line.split(" "), lead=INDENT)


def _print_folder(folder: FolderInfo, output_format: ReportFormat) -> None:
    """A folder of bags: one line per bag, then the totals; the unread as the fleet rule
    says (docs/fleet.md: a warning each, then one error line and exit 2)."""
    if output_format is ReportFormat.JSON:
        print_json(folder.to_dict())
    else:
        # The folder's path on a line of its own: as long as the user made it, never cut.
        print_line([Styled(folder.root, "bold"), f": {counted(len(folder.bags), 'bag')}"])
        table = Table(
            [Column("bag"), *(Column(c, numeric=True) for c in ("messages", "duration", "size"))]
        )
        for bag in folder.bags:
            shown = Path(bag.path).relative_to(folder.root) if bag.path else bag.path
            table.add_row(
                str(shown),
                f"{bag.message_count:,}",
                f"{bag.duration_s:.1f} s",
                _size(bag.size_bytes),
            )
        table.add_footer(
            "total",
            f"{folder.message_count:,}",
            f"{folder.duration_s:.1f} s",
            _size(folder.size_bytes),
        )
        print_table(table)
    from bagkit.cli.fleet_options import end_with_unread
    from bagkit.errors import not_read

    for path, why in folder.unread.items():
        warn(not_read(path, why))
    end_with_unread(len(folder.unread), len(folder.bags) + len(folder.unread))


@handle_errors
def info(  # noqa: PLR0917 (typer maps parameters to options)
    bag: str = typer.Argument(..., help=BAG_HELP, metavar="BAG", show_default=False),
    topic_name: bool = typer.Option(
        False, "--topic-name", "-t", help="Only print the topic names, one per line."
    ),
    verbose: bool = typer.Option(
        False, "--verbose", "-v", help="Also serialization, offered QoS and custom data in full."
    ),
    storage: str | None = typer.Option(
        None,
        "--storage",
        "-s",
        help="mcap, sqlite3 or rosbag1: fail if the bag is stored otherwise.",
    ),
    output_format: ReportFormat = typer.Option(
        ReportFormat.TABLE, "--format", help="table (for people) or json (for scripts)."
    ),
    check_crc: bool = typer.Option(
        True, "--crc/--no-crc", help="Check the CRC of chunks a salvage scan opens."
    ),
    exact_rates: bool = typer.Option(
        False,
        "--exact-rates",
        help="For a bag in storage, read the message indexes of the chunks at each topic's "
        "ends too (exact rates; a range request more per file).",
    ),
    distro: Distro = None,
) -> None:
    """Show what a bag holds (like ros2 bag info)."""
    if storage not in (None, "mcap", "sqlite3", "rosbag1"):
        raise fail(f"--storage {storage}: bagkit reads mcap, sqlite3 and rosbag1 bags")
    if is_url(bag) or (Path(bag).is_dir() and not (Path(bag) / "metadata.yaml").is_file()):
        from bagkit.fleet.listing import folder_info

        folder = folder_info(bag, check_crc=check_crc, exact_rates=exact_rates or None)
        if folder is not None:
            _print_folder(folder, output_format)
            return
    with common.status(f"reading {bag}"):
        result = bag_info(bag, check_crc=check_crc, exact_rates=exact_rates or None)
        services = [] if topic_name else _services(bag, result)
    if storage is not None and result.storage != storage:
        raise fail(f"{bag} is a {result.storage} bag, not {storage}")
    actions = action_summaries(result.topics)
    if topic_name:
        for topic in result.topics:
            sys.stdout.write(f"{topic.topic}\n")
    elif output_format is ReportFormat.JSON:
        print_json(
            {
                **result.to_dict(),
                "services": [s.to_dict() for s in services],
                "actions": [a.to_dict() for a in actions],
            }
        )
    else:
        _print_table(result, verbose)
        if services:
            _print_services(services)
        if actions:
            _print_actions(actions)
    for problem in result.problems:
        warn(problem)
