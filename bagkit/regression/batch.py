"""``golden check`` over many fixtures: lockstep checks as tasks on Dask, live checks here.

A lockstep check reads the fixture's bags and runs its processors in one process, so checks
spread over workers like the bags of ``stats summary``; each task writes its failure report
where a single check would (the workers must see the fixtures and ``failures`` at the same
paths: always so on a local cluster). Live checks replay through DDS on the wall clock: run
side by side they would load each other's nodes and share a ROS domain, so they run one after
another in this process.
"""

from __future__ import annotations

import functools
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag import BagError
from bagkit.fleet.execute import ItemDone, run_each
from bagkit.regression.spec import FixtureSpec, load_spec
from bagkit.storage.errors import StorageError

if TYPE_CHECKING:
    from distributed import Client

CheckJob = tuple[FixtureSpec, str]
"""A fixture and a mode (``lockstep`` or ``live``)."""


@dataclass(frozen=True, slots=True)
class FixtureOutcome:
    """What one check found, small enough to come back from a worker.

    Attributes:
        fixture: the fixture's name.
        mode: lockstep or live.
        passed: whether the outputs matched the golden's.
        summary: the failing topics and first divergences (:meth:`GoldenCheck.summary`).
        speedup: lockstep only, how many times faster than real time it ran.
        report: the failure report (``report.html``), when it failed.
        error: why the fixture's golden bag could not be read (not checked).
    """

    fixture: str
    mode: str
    passed: bool
    summary: str
    speedup: float | None = None
    report: Path | None = None
    error: str | None = None

    def to_dict(self) -> dict[str, object]:
        """The outcome as JSON values (``golden check --format json``)."""
        return {
            "fixture": self.fixture,
            "mode": self.mode,
            "passed": self.passed,
            "summary": self.summary,
            "speedup": self.speedup,
            "report": None if self.report is None else str(self.report),
            "error": self.error,
        }


def check_fixture(job: tuple[Path, str], *, failures: Path, import_root: str) -> FixtureOutcome:
    """Check one fixture directory in one mode; on failure write its report under ``failures``.

    ``import_root`` is put on ``sys.path`` first (a worker process does not share the
    caller's): processor factories import from the directory the command runs in.
    """
    from bagkit.regression.artefacts import write_failure_artefacts
    from bagkit.regression.check import run_check

    if import_root not in sys.path:
        sys.path.insert(0, import_root)
    directory, mode = job
    spec = load_spec(directory)
    with tempfile.TemporaryDirectory(prefix="bagkit-golden-") as tmp:
        try:
            result = run_check(spec, mode, Path(tmp))
        except (BagError, StorageError) as exc:  # reported among the others (docs/fleet.md)
            return FixtureOutcome(spec.name, mode, False, "", error=str(exc))
        report = None
        if not result.passed:
            folder = failures / f"{spec.name}-{result.mode}"
            write_failure_artefacts(result, folder)
            report = folder / "report.html"
    speedup = result.lockstep.speedup if result.lockstep is not None else None
    return FixtureOutcome(spec.name, mode, result.passed, result.summary(), speedup, report)


def check_fixtures(
    jobs: Sequence[CheckJob],
    failures: Path,
    *,
    client: Client | None = None,
    done: ItemDone | None = None,
    before_live: Callable[[CheckJob], None] | None = None,
) -> list[FixtureOutcome]:
    """Run every check of ``jobs``; outcomes in the order of ``jobs``.

    Lockstep checks run on ``client``'s workers (here without one) and report to ``done``
    with their index among the lockstep jobs; live checks run here, one after another, each
    announced to ``before_live``.

    Raises:
        SpecError: a spec cannot be checked in its mode.
        LiveRunError: a live run failed.
    """
    task = functools.partial(
        check_fixture, failures=failures.resolve(), import_root=str(Path.cwd())
    )
    paths = [(spec.directory.resolve(), mode) for spec, mode in jobs]
    lockstep = iter(run_each(task, [p for p in paths if p[1] == "lockstep"], client, done))
    outcomes = []
    for job, path in zip(jobs, paths, strict=True):
        if path[1] == "lockstep":
            outcomes.append(next(lockstep))
            continue
        if before_live is not None:
            before_live(job)
        outcomes.append(task(path))
    return outcomes
