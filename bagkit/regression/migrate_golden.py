"""``bagkit golden migrate``: a fixture's golden rewritten to today's definitions, then checked.

The golden is migrated (:func:`bagkit.surgery.migrate.migrate_bag`, the installed
definitions) into a hidden directory beside it and swapped in only when the migration
succeeded, so a failed one leaves the fixture as it was; then its lockstep check runs (when
the spec has a processor), which shows whether the system under test agrees with the
migrated golden.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from bagkit.regression.golden import GoldenCheck, check_lockstep
from bagkit.regression.spec import BAG_DIR, FixtureSpec
from bagkit.surgery.migrate import MigrateOptions, MigrateReport, migrate_bag


@dataclass(frozen=True, slots=True)
class GoldenMigration:
    """What ``golden migrate`` did to one fixture.

    Attributes:
        migration: the migration's report (no topic migrated: the golden was left alone).
        check: the lockstep check afterwards (None without a processor).
    """

    migration: MigrateReport
    check: GoldenCheck | None


def migrate_golden(spec: FixtureSpec, options: MigrateOptions, workdir: Path) -> GoldenMigration:
    """Migrate ``spec``'s golden to ``options``' target, then run its lockstep check.

    Raises:
        MigrateError: the migration cannot be made (the golden is left as it was).
        SpecError, RegressionError: the check cannot be run.
    """
    with tempfile.TemporaryDirectory(dir=spec.directory, prefix=".migrate-") as tmp:
        fresh = Path(tmp) / BAG_DIR
        report = migrate_bag(spec.bag, fresh, options)
        if report.migrated:
            old = Path(tmp) / "old"
            spec.bag.rename(old)
            fresh.rename(spec.bag)
            shutil.rmtree(old)
    check = check_lockstep(spec, workdir) if spec.processor is not None else None
    return GoldenMigration(report, check)
