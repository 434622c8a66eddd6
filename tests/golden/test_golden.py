"""The golden-bag regression suite: every fixture in lockstep, one in live replay through DDS.

``pytest tests/golden --update-golden`` rewrites the fixtures' expected outputs from lockstep
(accepting today's behaviour) instead of comparing. A failure writes ``report.json`` and PNG
plots to ``golden_failures/<fixture>-<mode>/`` and names that folder in its message.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bagkit.regression.golden import (
    GoldenCheck,
    check_lockstep,
    update_golden,
    write_failure_artefacts,
)
from bagkit.regression.live import check_live
from bagkit.regression.spec import FixtureSpec, find_fixtures

REPO = Path(__file__).resolve().parents[2]
FIXTURES = find_fixtures(REPO / "fixtures")
FAILURES = REPO / "golden_failures"


def fail_with_artefacts(check: GoldenCheck) -> None:
    folder = FAILURES / f"{check.spec.name}-{check.mode}"
    write_failure_artefacts(check, folder)
    pytest.fail(f"{check.summary()}\nreport and plots: {folder}", pytrace=False)


def test_there_are_fixtures() -> None:
    assert len(FIXTURES) >= 3, f"expected at least 3 fixtures in {REPO / 'fixtures'}"


@pytest.mark.parametrize("spec", FIXTURES, ids=[s.name for s in FIXTURES])
def test_lockstep(spec: FixtureSpec, tmp_path: Path, request: pytest.FixtureRequest) -> None:
    if request.config.getoption("--update-golden"):
        result = update_golden(spec)
        print(f"{spec.name}: expected outputs rewritten from lockstep: {result.output_counts}")
        return
    check = check_lockstep(spec, tmp_path)
    if not check.passed:
        fail_with_artefacts(check)


# The live mode runs the fixture with the most going on (faults raising and clearing alerts).
LIVE_FIXTURES = [s for s in FIXTURES if s.name == "faults"]


@pytest.mark.ros
@pytest.mark.parametrize("spec", LIVE_FIXTURES, ids=[s.name for s in LIVE_FIXTURES])
def test_live(spec: FixtureSpec, tmp_path: Path, request: pytest.FixtureRequest) -> None:
    """Nodes with use_sim_time, ``bagkit replay --clock`` of the inputs, ``bagkit record`` of
    the outputs, compared with the spec's live tolerances."""
    if request.config.getoption("--update-golden"):
        pytest.skip("expected outputs are rewritten from lockstep only")
    check = check_live(spec, tmp_path)
    if not check.passed:
        fail_with_artefacts(check)
