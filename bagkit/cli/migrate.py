"""``bagkit migrate``: a bag rewritten to today's message definitions (or another bag's, or a
package directory's)."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import (
    ReportFormat,
    console,
    err_console,
    handle_errors,
    note,
    print_json,
    status,
)
from bagkit.cli.selection_options import Distro
from bagkit.cli.surgery_options import Compression, Force, Format, Output, output_options
from bagkit.words import counted

HELP = """Rewrite BAG to other message definitions into a new bag OUT: by default those
installed today, or those stored in another bag (--to-bag), or those of an interface
package's source directory (--to-package DIR, its msg/ and srv/ files). Each topic whose
type is defined differently is rewritten message by message: fields with the same name and a
type the value fits are copied, new fields take their defaults (0, '', empty), and a rules
file (--rules) gives renames, computed fields (the condition language with arithmetic:
'temperature + 273.15'), fields dropped knowingly and a Python function as the last resort.
A field whose values would be lost with no rule saying so is refused unless --allow-drop.
Every migrated message is decoded with its new definition before it is written; topics
whose definition did not change are copied as they are. OUT keeps the QoS and custom_data of
BAG and gains custom_data bagkit.migrate, which names the rules that ran. On any error
nothing is written (exit 2). docs/regression.md, "When a message changes", walks through it.

Examples:

  bagkit migrate old_drive -o drive_v2 --rules battery_v2.yaml

  bagkit migrate humble_bag -o jazzy_bag
"""


@handle_errors
def migrate(
    bag: Path = typer.Argument(..., help="The bag to migrate (directory or file)."),
    *,
    output: Output,
    to_bag: Path | None = typer.Option(
        None, "--to-bag", help="Migrate to the definitions stored in this bag.", metavar="BAG"
    ),
    to_package: Path | None = typer.Option(
        None,
        "--to-package",
        help="Migrate to the .msg/.srv files of this package source directory.",
        metavar="DIR",
    ),
    rules: Path | None = typer.Option(
        None,
        "--rules",
        help="A YAML rules file (renames, compute, drop, function).",
        metavar="FILE",
    ),
    allow_drop: bool = typer.Option(
        False, "--allow-drop", help="Drop the values of fields that no rule carries over."
    ),
    compression: Compression = "zstd",
    force: Force = False,
    output_format: Format = ReportFormat.TABLE,
    distro: Distro = None,
) -> None:
    """Rewrite a bag to other message definitions."""
    from bagkit.migrate import Rules, Target, load_rules
    from bagkit.surgery.errors import SurgeryError
    from bagkit.surgery.migrate import MigrateOptions, migrate_bag

    if to_bag is not None and to_package is not None:
        raise SurgeryError("--to-bag and --to-package: choose one")
    if to_bag is not None:
        target = Target.from_bag(to_bag)
    elif to_package is not None:
        target = Target.from_package(to_package)
    else:
        target = Target()
    options = MigrateOptions(
        target=target,
        rules=load_rules(rules) if rules is not None else Rules(),
        rules_file=str(rules or ""),
        allow_drop=allow_drop,
        output=output_options(compression, force=force, check_crc=True),
    )
    with status(f"migrating {bag}"):
        report = migrate_bag(bag, output, options)
    if output_format == ReportFormat.JSON:
        print_json(report.to_dict())
        return
    for migration in report.migrated:
        console.print(
            f"{migration.topic.name} ({migration.topic.type}): {migration.migrated:,} "
            "messages migrated",
            highlight=False,
            soft_wrap=True,
        )
        for line in migration.changes:
            console.print(f"  {line}", highlight=False, soft_wrap=True)
        for rule in migration.rules_run:
            console.print(f"  rule: {rule}", highlight=False, soft_wrap=True)
        for dropped in migration.dropped:
            console.print(f"  dropped: {dropped}", highlight=False, soft_wrap=True)
    if not report.migrated:
        note(f"{bag}: no topic differs from {target.describe()}: copied as it is")
    written = report.rewrite
    console.print(
        f"wrote {written.output}: {counted(written.message_count, 'message')} "
        f"({counted(len(written.topic_counts), 'topic')}, {len(report.migrated)} migrated, "
        f"{len(report.unchanged)} unchanged)",
        highlight=False,
        soft_wrap=True,
    )
    for problem in written.problems:
        err_console.print(f"warning: {problem}", highlight=False, soft_wrap=True)
