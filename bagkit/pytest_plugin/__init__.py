"""pytest plugin (entry point ``pytest11``): every golden fixture is a test, no conftest needed.

Configure where fixtures live, in ``pytest.ini``/``pyproject.toml``::

    [tool.pytest.ini_options]
    golden_roots = ["fixtures"]

or per run with ``--golden-root DIR``. Each directory under a root holding a ``spec.yaml``
becomes one item per mode (``fixtures/takeoff/spec.yaml::lockstep``, ``::live``).
A spec with a ``health:`` contract adds one item per assertion: on the golden
(``::golden-health[/imu/data: gap > 300ms]``) and on each mode's outputs
(``::lockstep-health[...]``), so that a failure names the assertion.
``--golden-mode lockstep|live|all`` chooses the modes (default: all the spec lists);
``--update-golden`` accepts today's behaviour instead of comparing (lockstep outputs; a
fixture whose outputs are unchanged is not rewritten). A failure prints the verdict and the
path of its report (``golden_failures/<fixture>-<mode>/report.html``). ``--golden-summary
FILE`` writes a markdown verdict at the end (one table row per fixture and mode), for a CI job
summary. Under pytest-xdist each run is still made once, whatever ``--dist`` (``shared``).

Nothing here imports rclpy or the harness until a golden item runs.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from bagkit.pytest_plugin import shared
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.compare.result import TopicResult
    from bagkit.health import HealthReport
    from bagkit.regression.golden import GoldenCheck
    from bagkit.regression.spec import FixtureSpec

ROOTS = pytest.StashKey[list[Path]]()
GOLDEN = "golden"
SPEC_FILE = "spec.yaml"  # regression.spec's, not imported: that imports numpy
MODE_CHOICES = ("lockstep", "live", "all")
# Marks a domain the plugin chose, so that xdist workers know they may choose their own.
_CHOSEN_DOMAIN = "BAGKIT_PYTEST_CHOSEN_DOMAIN"
# user_properties of a golden item's reports: they cross xdist's worker boundary (and land in
# --junitxml as properties), so the summary is written from what the controller receives.
FIXTURE_PROPERTY = "golden_fixture"
MODE_PROPERTY = "golden_mode"
VERDICT_PROPERTY = "golden_verdict"
REPORT_PROPERTY = "golden_report"


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
    group.addoption(
        "--golden-summary",
        default=None,
        metavar="FILE",
        help="Golden fixtures: write a markdown verdict (a table per fixture and mode) to FILE.",
    )
    parser.addini("golden_roots", "Directories holding golden fixtures.", type="paths")
    parser.addini("golden_mode", "lockstep, live or all (default all).", default="all")


def _roots(config: pytest.Config) -> list[Path]:
    configured = [Path(p) for p in config.getini("golden_roots")]
    given = [Path(p) for p in config.getoption("golden_root")]
    return [p.resolve() for p in [*configured, *given, *_named_fixtures(config)]]


def _named_fixtures(config: pytest.Config) -> list[Path]:
    """Fixtures named on the command line (``pytest fixtures/incident``, or a folder of them):
    collected without ``golden_roots``, as a test file named there is."""
    if config.args_source != pytest.Config.ArgsSource.ARGS:
        return []
    found = []
    for arg in config.args:
        path = Path(arg.split("::")[0])
        if path.name == SPEC_FILE and path.is_file():
            found.append(path.parent)
        elif (path / SPEC_FILE).is_file() or (path.is_dir() and any(path.glob(f"*/{SPEC_FILE}"))):
            found.append(path)
    return found


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "golden: a golden-bag fixture (bagkit)")
    config.addinivalue_line("markers", "ros: starts real ROS 2 nodes over DDS")
    # A ROS message's type support imports the rosidl generators, and with them lark-parser
    # 0.12 (via rosidl_parser), which imports the deprecated sre_parse/sre_constants: not the
    # user's code, nor bagkit's, and nothing they can change.
    for module in ("sre_parse", "sre_constants"):
        config.addinivalue_line(
            "filterwarnings", f"ignore:module '{module}' is deprecated:DeprecationWarning:lark"
        )
    roots = _roots(config)
    config.stash[ROOTS] = roots
    summary = config.getoption("golden_summary")
    if summary and Path(summary).is_dir():
        raise pytest.UsageError(f"--golden-summary {summary}: a directory, not a file")
    if summary and not hasattr(config, "workerinput"):  # xdist workers report to the controller
        from bagkit.pytest_plugin.summary import GoldenSummary

        config.pluginmanager.register(GoldenSummary(Path(summary), config.rootpath))
    if not roots:
        return
    # Live runs stay on this machine and off other sessions' domains unless told otherwise.
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    _choose_domain(config)
    shared.check_worker(config)
    if config.args_source != pytest.Config.ArgsSource.ARGS:
        # `pytest` alone walks testpaths (or the current directory): add the roots it misses.
        walked = [Path(a).resolve() for a in config.args]
        config.args += [str(r) for r in roots if not any(r.is_relative_to(w) for w in walked)]


def _choose_domain(config: pytest.Config) -> None:
    """A ROS_DOMAIN_ID of this session's own, and one per pytest-xdist worker.

    Workers inherit the controller's environment: without a domain each, the live runs of two
    workers would see each other's nodes. A domain the user set is kept, workers included.
    """
    chosen = os.environ.get(_CHOSEN_DOMAIN)
    if getattr(config, "workerinput", None) is None:
        if "ROS_DOMAIN_ID" in os.environ:
            return
    elif chosen is None or chosen != os.environ.get("ROS_DOMAIN_ID"):
        return
    from bagkit.ros.domains import reserve
    from bagkit.ros.errors import RosError

    try:
        domain = str(reserve(1, os.getpid()))
    except RosError as exc:
        raise pytest.UsageError(str(exc)) from None
    os.environ["ROS_DOMAIN_ID"] = os.environ[_CHOSEN_DOMAIN] = domain


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node: Any) -> None:
    """pytest-xdist's controller starting a worker: hand it the directory where the workers
    share each fixture's run."""
    if node.config.stash.get(ROOTS, None):
        shared.hand_to_worker(node.config, node.workerinput)


@pytest.hookimpl(optionalhook=True, trylast=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """Under ``--dist loadgroup``, a golden fixture's run and its items on one worker; a
    scheduler of the user's own (a conftest's) comes first."""
    if config.getvalue("dist") != "loadgroup" or not config.stash.get(ROOTS, None):
        return None
    from bagkit.pytest_plugin.scheduling import GoldenRunScheduling

    return GoldenRunScheduling(config, log)


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
        if spec.health is not None:
            from bagkit.regression.health import assertion_names

            for name in assertion_names(spec.health):
                items.append(HealthItem.from_parent(self, spec=spec, mode=GOLDEN, assertion=name))
        for mode in modes:
            items.append(GoldenItem.from_parent(self, name=mode, spec=spec, mode=mode))
            if spec.health is not None:
                from bagkit.regression.health import assertion_names, outputs_contract

                for name in assertion_names(outputs_contract(spec.health, spec.outputs)):
                    items.append(HealthItem.from_parent(self, spec=spec, mode=mode, assertion=name))
        for item in items:
            item.add_marker("golden")
            if getattr(item, "mode", None) == "live":
                item.add_marker("ros")
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
        self.user_properties += [(FIXTURE_PROPERTY, spec.name), (MODE_PROPERTY, mode)]

    def runtest(self) -> None:
        from bagkit.regression.golden import update_golden

        if self.config.getoption("update_golden"):
            if self.mode != "lockstep":
                pytest.skip("expected outputs are rewritten from lockstep only")
            # once: under xdist's --dist each every worker has this item
            key = f"{self.spec.directory}::update"
            rewritten = shared.once(self.config, key, lambda: update_golden(self.spec).rewritten)
            outcome = "rewritten" if rewritten else "unchanged"
            self.user_properties.append((VERDICT_PROPERTY, f"outputs {outcome}"))
            print(f"{self.spec.name}: {outcome}")
            return
        check = run_once(self.config, self.spec, self.mode)
        self.user_properties.append((VERDICT_PROPERTY, verdict(check)))
        if not check.matched:  # the health items say whether the contract held
            report = _failures(self.config) / f"{self.spec.name}-{self.mode}" / "report.html"
            self.user_properties.append((REPORT_PROPERTY, str(report)))
            raise GoldenMismatchError(check, report)

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


def _failures(config: pytest.Config) -> Path:
    given = config.getoption("golden_failures")
    return Path(given).resolve() if given else config.rootpath / "golden_failures"


def run_once(config: pytest.Config, spec: FixtureSpec, mode: str) -> GoldenCheck:
    """``spec``'s run in ``mode``, once per session, pytest-xdist's workers included (its item
    and its health items share it); a run whose outputs differ leaves its report under the
    failures folder."""
    from bagkit.regression.artefacts import write_failure_artefacts
    from bagkit.regression.check import run_check

    def run() -> GoldenCheck:
        with (
            shared.domain_turn(config) if mode == "live" else nullcontext(),
            tempfile.TemporaryDirectory(prefix=f"golden-{spec.name}-") as tmp,
        ):
            check = run_check(spec, mode, Path(tmp))
            if not check.matched:
                write_failure_artefacts(check, _failures(config) / f"{spec.name}-{mode}")
        return check

    return shared.once(config, f"{spec.directory}::{mode}", run)


class HealthItem(pytest.Item):
    """One assertion of a spec's ``health:`` contract, on the golden or on a mode's outputs."""

    def __init__(self, *, spec: FixtureSpec, mode: str, assertion: str, **kwargs: Any) -> None:
        super().__init__(name=f"{mode}-health[{assertion}]", **kwargs)
        self.spec = spec
        self.mode = mode
        self.assertion = assertion

    def runtest(self) -> None:
        from bagkit.regression.health import by_name, describe, outputs_contract

        if self.config.getoption("update_golden"):
            pytest.skip("--update-golden rewrites outputs; the contract is checked without it")
        assert self.spec.health is not None
        contract = self.spec.health
        if self.mode == GOLDEN:
            report = self._golden_health()
        else:
            try:
                check = run_once(self.config, self.spec, self.mode)
            except Exception as exc:
                pytest.skip(f"the {self.mode} run failed: {exc}")
            assert check.health is not None
            report = check.health
            contract = outputs_contract(contract, self.spec.outputs)
        assertion = by_name(report, contract)[self.assertion]
        if not assertion.passed:
            where = "the golden" if self.mode == GOLDEN else f"the {self.mode} outputs"
            raise HealthBrokenError(f"{describe(assertion, report.start_ns)} ({where})")

    def _golden_health(self) -> HealthReport:
        from bagkit.health import check_bag

        assert self.spec.health is not None
        contract = self.spec.health
        key = f"{self.spec.directory}::{GOLDEN}"
        return shared.once(self.config, key, lambda: check_bag(self.spec.bag, contract))

    def repr_failure(
        self,
        excinfo: pytest.ExceptionInfo[BaseException],
        style: Any = None,
    ) -> str | Any:
        from bagkit.errors import BagkitError

        if isinstance(excinfo.value, HealthBrokenError | BagkitError):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style=style)

    def reportinfo(self) -> tuple[Path, int | None, str]:
        return self.path, None, f"golden fixture {self.spec.name} [{self.name}]"


class HealthBrokenError(Exception):
    """An assertion of a spec's ``health:`` contract that does not hold."""


def verdict(check: GoldenCheck, most: int = 3) -> str:
    """One line: what matched, or the failing topics with their fields and counts."""
    topics = check.report.topics
    if check.drift:
        drifted = [f"{d.topic}: drifted ({'; '.join(d.changes)})" for d in check.drift]
        more = f"; and {counted(len(drifted) - most, 'more topic')}" if len(drifted) > most else ""
        return "; ".join(drifted[:most]) + more
    if check.passed:
        matched = sum(t.matched for t in topics)
        return f"{counted(len(topics), 'topic')}, {counted(matched, 'message')} match the golden"
    failing = [_topic_verdict(t) for t in topics if not t.passed]
    more = f"; and {counted(len(failing) - most, 'more topic')}" if len(failing) > most else ""
    return "; ".join(failing[:most]) + more


def _topic_verdict(topic: TopicResult) -> str:
    parts = [f.describe() for f in topic.failed_fields]
    parts += topic.shape_fields
    parts += [
        f"{n} {what}" for n, what in ((topic.missing, "missing"), (topic.extra, "extra")) if n
    ]
    return f"{topic.topic}: {', '.join(parts) or 'differs'}"
