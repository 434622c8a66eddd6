"""pytest plugin (entry point ``pytest11``): every golden fixture is a test, no conftest needed.

Configure where fixtures live, in ``pytest.ini``/``pyproject.toml``::

    [tool.pytest.ini_options]
    golden_roots = ["fixtures"]

or per run with ``--golden-root DIR``. Each directory under a root holding a ``spec.yaml``
becomes one item per mode (``fixtures/takeoff/spec.yaml::lockstep``, ``::live``).
``--golden-mode lockstep|live|all`` chooses the modes (default: all the spec lists);
``--update-golden`` accepts today's behaviour instead of comparing (lockstep outputs; a
fixture whose outputs are unchanged is not rewritten). A failure prints the verdict and the
path of its report (``golden_failures/<fixture>-<mode>/report.html``).

Nothing here imports rclpy or the harness until a golden item runs.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from bagkit.regression.golden import GoldenCheck
    from bagkit.regression.spec import FixtureSpec

ROOTS = pytest.StashKey[list[Path]]()
SPEC_FILE = "spec.yaml"
MODE_CHOICES = ("lockstep", "live", "all")


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("golden", "golden-bag regression (bagkit)")
    group.addoption(
        "--golden-root",
        action="append",
        default=[],
        metavar="DIR",
        help="Collect fixture directories (holding spec.yaml) under DIR; repeatable.",
    )
    group.addoption(
        "--golden-mode",
        choices=MODE_CHOICES,
        default=None,
        help="Golden fixtures: run lockstep, live, or all the modes each spec lists (default).",
    )
    group.addoption(
        "--update-golden",
        action="store_true",
        help="Golden fixtures: accept today's behaviour (rewrite changed outputs), do not compare.",
    )
    group.addoption(
        "--golden-failures",
        default=None,
        metavar="DIR",
        help="Where failing fixtures' reports go (default: golden_failures under the rootdir).",
    )
    parser.addini("golden_roots", "Directories holding golden fixtures.", type="paths")
    parser.addini("golden_mode", "lockstep, live or all (default all).", default="all")


def _roots(config: pytest.Config) -> list[Path]:
    configured = [Path(p) for p in config.getini("golden_roots")]
    given = [Path(p) for p in config.getoption("golden_root")]
    return [p.resolve() for p in [*configured, *given]]


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "golden: a golden-bag fixture (bagkit)")
    config.addinivalue_line("markers", "ros: starts real ROS 2 nodes over DDS")
    roots = _roots(config)
    config.stash[ROOTS] = roots
    if not roots:
        return
    # Live runs stay on this machine and off other sessions' domains unless told otherwise.
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(100 + os.getpid() % 130))
    if config.args_source != pytest.Config.ArgsSource.ARGS:
        # `pytest` alone walks testpaths (or the current directory): add the roots it misses.
        walked = [Path(a).resolve() for a in config.args]
        config.args += [str(r) for r in roots if not any(r.is_relative_to(w) for w in walked)]


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    if file_path.name != SPEC_FILE:
        return None
    if not any(file_path.is_relative_to(r) for r in parent.config.stash.get(ROOTS, [])):
        return None
    return GoldenFile.from_parent(parent, path=file_path)


class GoldenFile(pytest.File):
    """A fixture's ``spec.yaml``: one item per mode."""

    def collect(self) -> list[pytest.Item]:
        from bagkit.regression.spec import load_spec

        spec = load_spec(self.path)
        chosen = self.config.getoption("golden_mode") or self.config.getini("golden_mode")
        if chosen not in MODE_CHOICES:
            raise pytest.UsageError(f"golden_mode must be one of {', '.join(MODE_CHOICES)}")
        modes = [m for m in spec.modes if chosen in {"all", m}]
        items: list[pytest.Item] = []
        for mode in modes:
            item = GoldenItem.from_parent(self, name=mode, spec=spec, mode=mode)
            item.add_marker("golden")
            if mode == "live":
                item.add_marker("ros")
            items.append(item)
        return items

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException]) -> str | Any:  # type: ignore[override]
        from bagkit.errors import BagkitError

        if isinstance(excinfo.value, BagkitError):
            return f"error: {excinfo.value}"
        return super().repr_failure(excinfo)


class GoldenMismatchError(Exception):
    """A fixture whose candidate differs from its golden."""

    def __init__(self, check: GoldenCheck, report: Path) -> None:
        super().__init__(f"{check.summary()}\nreport: {report}")


class GoldenItem(pytest.Item):
    """One fixture in one mode: run, compare, write the report on a failure."""

    def __init__(self, *, spec: FixtureSpec, mode: str, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.spec = spec
        self.mode = mode

    def runtest(self) -> None:
        from bagkit.regression.artefacts import write_failure_artefacts
        from bagkit.regression.check import run_check
        from bagkit.regression.golden import update_golden

        if self.config.getoption("update_golden"):
            if self.mode != "lockstep":
                pytest.skip("expected outputs are rewritten from lockstep only")
            update = update_golden(self.spec)
            print(f"{self.spec.name}: {'rewritten' if update.rewritten else 'unchanged'}")
            return
        with tempfile.TemporaryDirectory(prefix=f"golden-{self.spec.name}-") as tmp:
            check = run_check(self.spec, self.mode, Path(tmp))
            if not check.passed:
                folder = self._failures() / f"{self.spec.name}-{self.mode}"
                write_failure_artefacts(check, folder)
                raise GoldenMismatchError(check, folder / "report.html")

    def _failures(self) -> Path:
        given = self.config.getoption("golden_failures")
        return Path(given).resolve() if given else self.config.rootpath / "golden_failures"

    def repr_failure(
        self,
        excinfo: pytest.ExceptionInfo[BaseException],
        style: Any = None,
    ) -> str | Any:
        from bagkit.errors import BagkitError

        if isinstance(excinfo.value, GoldenMismatchError | BagkitError):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style=style)

    def reportinfo(self) -> tuple[Path, int | None, str]:
        return self.path, None, f"golden fixture {self.spec.name} [{self.mode}]"
