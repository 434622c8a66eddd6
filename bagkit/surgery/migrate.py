"""``bagkit migrate``: a bag rewritten to other definitions, through the rewrite of ``filter``.

Each topic is planned first (:func:`bagkit.migrate.migrate_topic`): a topic whose type the
target defines differently has its payloads rewritten (in bulk per chunk where the layouts
allow it, :mod:`bagkit.migrate.bulk`); chunks without one are copied as they are stored
(:func:`~bagkit.surgery.rewrite.rewrite_topics`; non-MCAP inputs message by message).
Nothing is written before every plan is made, and an error on any message removes what was
written (:class:`~bagkit.surgery.output.OutputBag`): a failed migration leaves no output.
The output keeps the inputs' QoS and ``custom_data`` and gains ``bagkit.migrate``, a JSON list
with one entry per migration (the target, the rules file, per topic the changes, the rules
that ran and the fields dropped).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bagkit.bag import BagReader, safe_json
from bagkit.migrate import Rules, Target, TopicMigration, migrate_topic
from bagkit.native import keep_freed_memory
from bagkit.surgery.assumed import check_assumed_definitions
from bagkit.surgery.message_copy import Progress
from bagkit.surgery.options import OutputOptions, PayloadRewrites, RewriteReport
from bagkit.surgery.rewrite import check_output, rewrite_topics

CUSTOM_DATA_KEY = "bagkit.migrate"


@dataclass(frozen=True)
class MigrateOptions:
    """What ``bagkit migrate`` is asked.

    Attributes:
        target: the definitions to migrate to (default: the installed ones).
        rules: the rules file's rules, and ``rules_file`` its path (for the record).
        allow_drop: drop the values of fields no rule carries over instead of refusing.
        output: how the output is written.
    """

    target: Target = field(default_factory=Target)
    rules: Rules = field(default_factory=Rules)
    rules_file: str = ""
    allow_drop: bool = False
    output: OutputOptions = field(default_factory=OutputOptions)


@dataclass
class MigrateReport:
    """What a migration did.

    Attributes:
        migrated: the topics rewritten (their changes, rules run, fields dropped, counts).
        unchanged: topics copied as they were (same definition, or none in the target).
        rewrite: the copy's own report (files, counts, problems).
    """

    migrated: list[TopicMigration]
    unchanged: list[str]
    rewrite: RewriteReport

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            **self.rewrite.to_dict(),
            "migrated": [_topic_entry(m) | {"messages": m.migrated} for m in self.migrated],
            "unchanged": self.unchanged,
        }


def plan_migrations(bag: Path, options: MigrateOptions) -> tuple[list[TopicMigration], list[str]]:
    """The topics of ``bag`` that ``options`` migrate, and the others.

    Raises:
        BagError: the bag cannot be opened. MigrateError: a topic cannot be migrated.
        SurgeryError: a topic's assumed definition does not decode its messages.
    """
    with BagReader(bag, allow_empty=True) as reader:
        return _plan(reader, options)


def _plan(reader: BagReader, options: MigrateOptions) -> tuple[list[TopicMigration], list[str]]:
    """:func:`plan_migrations` of an open reader."""
    check_assumed_definitions(reader)
    migrated: list[TopicMigration] = []
    unchanged: list[str] = []
    for name, info in sorted(reader.topics.items()):
        stored = reader.topic_definitions.get(name, reader.definitions.get(info.type))
        plan = migrate_topic(
            info, stored, options.target, options.rules, allow_drop=options.allow_drop
        )
        if plan is None:
            unchanged.append(name)
        else:
            migrated.append(plan)
    return migrated, unchanged


def migrate_bag(
    bag: Path, output: Path, options: MigrateOptions, progress: Progress | None = None
) -> MigrateReport:
    """Rewrite ``bag`` to ``options.target``'s definitions into the new bag ``output``.

    Raises:
        BagError: the bag cannot be opened. MigrateError (RuleError, DataLossError): the
        migration cannot be made; nothing is written. SurgeryError: the output cannot be.
    """
    check_output([bag], output, options.output)
    with BagReader(bag, allow_empty=True) as reader:
        migrated, unchanged = _plan(reader, options)
        previous = reader.metadata.custom_data.get(CUSTOM_DATA_KEY, "") if reader.metadata else ""
    # Each opened chunk's buffers (decompressed, rebuilt, compressed) are freed and allocated
    # again for the next: kept by glibc instead of returned to the kernel, they are not paid
    # for in page faults chunk after chunk (benchmarks/README.md, "bagkit migrate").
    keep_freed_memory()
    entry = {
        "target": options.target.describe(),
        "rules_file": options.rules_file,
        "topics": {m.topic.name: _topic_entry(m) for m in migrated},
    }
    rewrites = PayloadRewrites(
        {m.topic.name: m for m in migrated},
        {CUSTOM_DATA_KEY: json.dumps([*_entries(previous), entry])},
    )
    report = rewrite_topics(bag, output, rewrites, options.output)
    return MigrateReport(migrated, unchanged, report)


def _topic_entry(migration: TopicMigration) -> dict[str, Any]:
    return {
        "topic": migration.topic.name,
        "type": migration.topic.type,
        "changes": migration.changes,
        "rules": migration.rules_run,
        "dropped": migration.dropped,
    }


def _entries(previous: str) -> list[Any]:
    """The entries of earlier migrations (an unreadable value is kept as its text)."""
    if not previous:
        return []
    try:
        found = safe_json.loads(previous)
    except ValueError:
        return [previous]
    return found if isinstance(found, list) else [found]
