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
# The campaign in parts of equal size, so that the test workers share it; each part runs its
# cases on one fuzz worker, as many as there are test workers run at once.
PARTS = 10


@pytest.mark.timeout(1200)
@pytest.mark.parametrize("part", range(PARTS))
def test_every_fuzzed_input_keeps_the_promise(tmp_path: Path, part: int) -> None:
    numbers = range(part * CASES // PARTS, (part + 1) * CASES // PARTS)
    cases, outcomes = fuzz.run_campaign(
        SEED,
        numbers,
        tmp_path,
        jobs=1,
        timeout=30.0,
        subprocess_sample=SUBPROCESS_RUNS,
        full_fixtures=False,
        campaign_size=CASES,
    )
    assert len(outcomes) >= len(numbers) * len(fuzz.campaign.COMMANDS)
    failed = [o for o in outcomes if o.category != "clean"]
    assert not failed, f"{len(failed)} of {len(outcomes)} runs broke the promise\n" + fuzz.report(
        cases, outcomes
    )
