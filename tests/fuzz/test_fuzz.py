"""The fuzz target on a fixed seed, CI-sized: every run must keep the promise (one ``error:``
line or success; no traceback, hang, crash or memory bomb). On failure, each distinct finding is
listed with the recipe of the first case that showed it; rebuild and rerun one case with
``python tests/fuzz/fuzz.py --seed 2026 --small-fixtures --case N --keep DIR``."""

from __future__ import annotations

from pathlib import Path

import fuzz
import pytest

SEED = 2026
CASES = 340  # x 3 commands = 1,020 runs in-process
SUBPROCESS_RUNS = 8  # of those, repeated as real `bagkit` processes (~1 s each to start)


# About 90 s on an idle 2-core machine; several times that when it is shared.
@pytest.mark.timeout(1200)
def test_every_fuzzed_input_keeps_the_promise(tmp_path: Path) -> None:
    cases, outcomes = fuzz.run_campaign(
        SEED,
        range(CASES),
        tmp_path,
        jobs=2,
        timeout=30.0,
        subprocess_sample=SUBPROCESS_RUNS,
        full_fixtures=False,
    )
    assert len(outcomes) >= 1000
    failed = [o for o in outcomes if o.category != "clean"]
    assert not failed, f"{len(failed)} of {len(outcomes)} runs broke the promise\n" + fuzz.report(
        cases, outcomes
    )
