"""bagkit's pytest plugin (entry point pytest11), run by pytest itself in a fresh directory
holding only a stranger's fixture: no conftest, the plugin does everything."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest
import yaml
from doubler_fixture import digest, write_core, write_fixture

from bagkit.regression.golden import update_golden
from bagkit.regression.spec import load_spec
from bagkit.ros.domains import FIRST, LAST

pytest_plugins = ["pytester"]

INI = "[pytest]\npythonpath = .\ngolden_roots = fixtures\n"


@pytest.fixture
def project(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A directory with pytest.ini, the doubler core and its fixture, outputs accepted."""
    root = pytester.path
    (root / "pytest.ini").write_text(INI)
    write_core(root)
    fixture = write_fixture(root / "fixtures" / "ramp")
    monkeypatch.syspath_prepend(str(root))
    assert update_golden(load_spec(fixture)).rewritten  # the first outputs
    return root


def test_a_passing_fixture_is_one_item_per_mode(project: Path, pytester: pytest.Pytester) -> None:
    result = pytester.runpytest_subprocess("-v")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*fixtures/ramp/spec.yaml::lockstep PASSED*"])


def test_a_changed_constant_fails_naming_topic_field_and_report(
    project: Path, pytester: pytest.Pytester
) -> None:
    write_core(project, factor=2.001)
    result = pytester.runpytest_subprocess()
    result.assert_outcomes(failed=1)
    out = result.stdout.str()
    assert "ramp (lockstep): FAIL" in out
    assert "/doubled" in out and "data (max |err|" in out
    assert "/sum" not in out.split("report:")[0].split("FAIL", 1)[1].split("\n")[1]
    report_dir = project / "golden_failures" / "ramp-lockstep"
    assert f"report: {report_dir / 'report.html'}" in out
    report = json.loads((report_dir / "report.json").read_text())
    failing = {t["topic"]: t for t in report["topics"] if not t["passed"]}
    assert set(failing) == {"/doubled"}
    assert failing["/doubled"]["failed_fields"] == ["data"]
    assert (report_dir / "report.html").stat().st_size > 0


def test_update_golden_accepts_a_change_and_is_idempotent(
    project: Path, pytester: pytest.Pytester
) -> None:
    fixture = project / "fixtures" / "ramp"
    unchanged = digest(fixture)
    pytester.runpytest_subprocess("--update-golden").assert_outcomes(passed=1)
    assert digest(fixture) == unchanged, "accepting unchanged behaviour rewrote files"

    write_core(project, factor=3.0)
    pytester.runpytest_subprocess("--update-golden").assert_outcomes(passed=1)
    accepted = digest(fixture)
    assert accepted != unchanged
    assert accepted.keys() == unchanged.keys()
    pytester.runpytest_subprocess().assert_outcomes(passed=1)
    pytester.runpytest_subprocess("--update-golden").assert_outcomes(passed=1)
    assert digest(fixture) == accepted


def test_golden_root_option_and_mode_filter(project: Path, pytester: pytest.Pytester) -> None:
    (project / "pytest.ini").write_text("[pytest]\npythonpath = .\n")
    # no root configured: the spec is not collected (and the plugin stays out of the way)
    assert pytester.runpytest_subprocess().ret == pytest.ExitCode.NO_TESTS_COLLECTED
    pytester.runpytest_subprocess("--golden-root", "fixtures").assert_outcomes(passed=1)
    only_live = pytester.runpytest_subprocess("--golden-root", "fixtures", "--golden-mode", "live")
    assert only_live.ret == pytest.ExitCode.NO_TESTS_COLLECTED


def test_a_fixture_named_on_the_command_line_is_collected_without_roots(
    project: Path, pytester: pytest.Pytester
) -> None:
    """``pytest fixtures/ramp --golden-mode lockstep`` (docs/regression.md) in a project that
    configures no golden_roots: the fixture named, or a folder of fixtures, is collected."""
    (project / "pytest.ini").write_text("[pytest]\npythonpath = .\n")
    for named in ("fixtures/ramp", "fixtures", "fixtures/ramp/spec.yaml"):
        result = pytester.runpytest_subprocess(named, "--golden-mode", "lockstep")
        result.assert_outcomes(passed=1)


def test_ordinary_tests_beside_the_fixtures_still_run(
    project: Path, pytester: pytest.Pytester
) -> None:
    pytester.makepyfile(test_plain="def test_one():\n    assert 1 + 1 == 2\n")
    result = pytester.runpytest_subprocess("-v")
    result.assert_outcomes(passed=2)
    # explicit arguments: only what they name
    pytester.runpytest_subprocess("test_plain.py").assert_outcomes(passed=1)


def test_a_broken_spec_is_one_error_line(project: Path, pytester: pytest.Pytester) -> None:
    spec = project / "fixtures" / "ramp" / "spec.yaml"
    spec.write_text(spec.read_text().replace("doubler_core:make_processors", "doubler_core"))
    result = pytester.runpytest_subprocess()
    assert result.ret == pytest.ExitCode.INTERRUPTED
    result.stdout.fnmatch_lines(["*error: *processor must read module.path:function*"])
    assert "Traceback" not in result.stdout.str()


_WRITE_DOMAIN = """
import os, pathlib

def test_domain_{n}(worker_id):
    pathlib.Path("domain_{n}").write_text(worker_id + " " + os.environ["ROS_DOMAIN_ID"])
"""


@pytest.mark.parametrize("users_domain", [None, "42"], ids=["chosen", "users"])
def test_each_xdist_worker_gets_a_domain_of_its_own_unless_the_user_set_one(
    project: Path,
    pytester: pytest.Pytester,
    monkeypatch: pytest.MonkeyPatch,
    users_domain: str | None,
) -> None:
    """Workers inherit the controller's environment: two workers' live runs must not share a
    domain the plugin chose, nor one another session holds (this one's); a domain the user set
    holds everywhere."""
    held = {os.environ["ROS_DOMAIN_ID"], os.environ["BAGKIT_TEST_SPARE_DOMAIN_ID"]}
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    if users_domain is not None:
        monkeypatch.setenv("ROS_DOMAIN_ID", users_domain)
    for n in range(4):
        pytester.makepyfile(**{f"test_domain_{n}": _WRITE_DOMAIN.format(n=n)})
    result = pytester.runpytest_subprocess("-n", "2", "-p", "xdist", "--dist", "loadfile")
    result.assert_outcomes(passed=5)  # the fixture's lockstep item too
    seen = dict(p.read_text().split() for p in project.glob("domain_*"))
    assert set(seen) == {"gw0", "gw1"}, seen
    if users_domain is None:
        assert len(set(seen.values())) == 2, seen
        assert not held & set(seen.values()), (held, seen)
        assert all(FIRST <= int(d) <= LAST for d in seen.values()), seen
    else:
        assert set(seen.values()) == {users_domain}


_COUNTED = '''

def counted_processors():
    """The doubler, and a line in runs.log for each run that makes it."""
    import os

    with open("runs.log", "a") as log:
        log.write(f"{os.environ['PYTEST_XDIST_WORKER']}\\n")
    if FACTOR < 0:
        raise ValueError("a negative factor")
    return make_processors()
'''


@pytest.fixture
def counted(project: Path) -> Path:
    """The project's fixture with a health contract (an item per assertion beside the run's
    item, sharing its run) and a factory that logs each run to ``runs.log``."""
    core = project / "doubler_core.py"
    core.write_text(core.read_text() + _COUNTED)
    spec_file = project / "fixtures" / "ramp" / "spec.yaml"
    spec = yaml.safe_load(spec_file.read_text())
    spec["processor"] = "doubler_core:counted_processors"
    spec["health"] = {"topics": {t: {"max_gap": "2s"} for t in ("/value", "/doubled", "/sum")}}
    spec_file.write_text(yaml.safe_dump(spec))
    return project / "runs.log"


def item_workers(output: str) -> dict[str, set[str]]:
    """Item (``lockstep``, ``lockstep-health[...]``) -> the xdist workers that ran it (``-v``)."""
    found: dict[str, set[str]] = {}
    for worker, item in re.findall(
        r"\[(gw\d+)\] \[ *\d+%\] \w+ \S+spec\.yaml::(.+?) *$", output, re.M
    ):
        found.setdefault(item, set()).add(worker)
    return found


@pytest.mark.parametrize("dist", ["load", "each"])
def test_under_xdist_a_run_is_made_once_for_its_items_on_every_worker(
    counted: Path, pytester: pytest.Pytester, dist: str
) -> None:
    """The lockstep item and its 4 health items share one run, whichever workers xdist gives
    them to (``each``: all of them to both)."""
    result = pytester.runpytest_subprocess("-v", "-n", "2", "-p", "xdist", "--dist", dist)
    items = 6 + 1 + 4  # health on the golden (3 topics), the run, health on its 2 outputs
    result.assert_outcomes(passed=items * (2 if dist == "each" else 1))
    assert counted.read_text().count("\n") == 1, counted.read_text()
    if dist == "each":
        ran = item_workers(result.stdout.str())
        assert ran["lockstep"] == {"gw0", "gw1"}
        assert len(ran) == items and all(w == {"gw0", "gw1"} for w in ran.values()), ran


def test_under_loadgroup_a_runs_items_are_one_group(
    counted: Path, pytester: pytest.Pytester
) -> None:
    """``--dist loadgroup``: the run's items go to one worker (none waits on another's run),
    and the golden's health items to one worker."""
    result = pytester.runpytest_subprocess("-v", "-n", "2", "-p", "xdist", "--dist", "loadgroup")
    result.assert_outcomes(passed=6 + 1 + 4)
    assert counted.read_text().count("\n") == 1, counted.read_text()
    ran = item_workers(result.stdout.str())
    for group in ("golden-health[", "lockstep"):
        workers = set().union(*(w for item, w in ran.items() if item.startswith(group)))
        assert len(workers) == 1, ran


def test_under_xdist_a_failed_run_fails_each_workers_item_once_made(
    counted: Path, pytester: pytest.Pytester
) -> None:
    """The run's exception crosses to the other worker: its item fails with the same error,
    its health items are skipped naming it, and the run was made once."""
    write_core(counted.parent, factor=-1.0)
    core = counted.parent / "doubler_core.py"
    core.write_text(core.read_text() + _COUNTED)
    result = pytester.runpytest_subprocess("-rA", "-n", "2", "-p", "xdist", "--dist", "each")
    result.assert_outcomes(passed=2 * 6, failed=2, skipped=2 * 4)
    assert counted.read_text().count("\n") == 1, counted.read_text()
    out = result.stdout.str()
    failure = "processor doubler_core:counted_processors failed: ValueError: a negative factor"
    failed_on = re.findall(rf"^\[(gw\d)\] linux .*\n{re.escape(failure)}$", out, re.M)
    assert sorted(failed_on) == ["gw0", "gw1"], out  # each worker's ::lockstep
    assert "SKIPPED [8] " in out and f"the lockstep run failed: {failure}" in out, out


# A worker that cannot reach the controller's directory, as one on another machine (--tx ssh).
_ELSEWHERE = """
import pytest

@pytest.hookimpl(wrapper=True)
def pytest_configure_node(node):
    yield
    node.workerinput["bagkit_golden_shared"] = "/nonexistent/elsewhere"
"""


def test_workers_that_cannot_share_runs_stop_the_session(
    counted: Path, pytester: pytest.Pytester
) -> None:
    pytester.makeconftest(_ELSEWHERE)
    result = pytester.runpytest_subprocess("-n", "2", "-p", "xdist")
    assert result.ret != pytest.ExitCode.OK
    result.stdout.fnmatch_lines(["*UsageError: golden fixtures under pytest-xdist share*"])
    assert "/nonexistent/elsewhere is not on this machine" in result.stdout.str()
    assert not counted.exists()  # no run made


# A process of each live run beside the thermostat's node: a line in turns.log when the run
# starts its system, one when it stops it (SIGINT).
_TURN = """
import pathlib, signal, sys

def log(what):
    with pathlib.Path("turns.log").open("a") as turns:
        turns.write(f"{what} {pathlib.Path(sys.argv[1]).name}\\n")

log("start")
try:
    signal.pause()
except KeyboardInterrupt:
    log("stop")
"""


@pytest.mark.ros
def test_live_runs_of_workers_sharing_the_users_domain_take_turns(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two fixtures' live runs on two workers, on one ROS_DOMAIN_ID the user set: run at once,
    each fixture's node would see both replays (and its recorder both nodes' outputs); they run
    one after the other, and both pass."""
    example = Path(__file__).resolve().parents[2] / "examples" / "thermostat"
    root = pytester.path
    shutil.copytree(example, root, dirs_exist_ok=True, ignore=shutil.ignore_patterns("__pycache__"))
    (root / "turn.py").write_text(_TURN)
    office = root / "fixtures" / "office"
    spec = yaml.safe_load((office / "spec.yaml").read_text())
    spec["launch"] = [spec["launch"], "python turn.py {fixture}"]
    (office / "spec.yaml").write_text(yaml.safe_dump(spec))
    shutil.copytree(office, root / "fixtures" / "annex")
    monkeypatch.setenv("ROS_DOMAIN_ID", os.environ["BAGKIT_TEST_SPARE_DOMAIN_ID"])
    result = pytester.runpytest_subprocess(
        "-n", "2", "-p", "xdist", "--golden-mode", "live", "--golden-failures", "failures"
    )
    result.assert_outcomes(passed=2)
    turns = [line.split() for line in (root / "turns.log").read_text().splitlines()]
    first, second = turns[0][1], turns[2][1]
    assert turns == [["start", first], ["stop", first], ["start", second], ["stop", second]], turns
    assert {first, second} == {"office", "annex"}
