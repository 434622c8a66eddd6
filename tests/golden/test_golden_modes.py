"""``golden check`` on copies of the repository's fast fixture: a fixture is checked only in the
modes its spec lists (as the pytest plugin runs it) and the CLI says which it left out; a
failure's divergence lines fit 80 columns."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import yaml

from tests.bagkit_runs import bagkit_in_process

REPO = Path(__file__).resolve().parents[2]


def _fixture(tmp_path: Path, name: str, modes: list[str], **spec_keys: object) -> Path:
    """A copy of the repository's fast fixture named ``name``, held to ``modes``."""
    folder = tmp_path / name
    shutil.copytree(REPO / "fixtures" / "fast", folder)
    spec = yaml.safe_load((folder / "spec.yaml").read_text())
    (folder / "spec.yaml").write_text(yaml.safe_dump({**spec, "modes": modes, **spec_keys}))
    return folder


def test_live_on_a_lockstep_only_fixture_is_one_error_line(tmp_path: Path) -> None:
    fast = _fixture(tmp_path, "fast", ["lockstep"])
    for mode in (["--mode", "live"], ["--live"]):
        done = bagkit_in_process(["golden", "check", fast, *mode])
        assert done.returncode == 2, done.stderr
        assert done.stderr.splitlines() == [
            "error: fast: its spec's modes are lockstep only, so it is not checked live"
        ]
        assert done.stdout == ""


def test_a_fixture_held_to_other_modes_is_left_out_with_a_warning(tmp_path: Path) -> None:
    fast = _fixture(tmp_path, "fast", ["lockstep"])
    live = _fixture(tmp_path, "drive", ["live"])
    failures = tmp_path / "failures"
    done = bagkit_in_process(
        ["golden", "check", fast, live, "--workers", "0", "--failures", failures]
    )
    assert done.returncode == 0, done.stderr
    assert (
        "warning: drive: its spec's modes are live only, so it is not checked lockstep"
        in done.stderr.splitlines()
    )
    assert done.stdout.splitlines()[0] == "fast (lockstep): pass"


def test_divergence_lines_fit_80_columns_and_say_what_the_report_says(tmp_path: Path) -> None:
    nodes = {"data_logger": {}, "alert_system": {}, "sensor_fusion": {"accel_sigma": 0.31}}
    fast = _fixture(tmp_path, "fast", ["lockstep"], processor_args={"nodes": nodes})
    failures = tmp_path / "failures"
    done = bagkit_in_process(
        ["golden", "check", fast, "--workers", "0", "--failures", failures], env={"COLUMNS": "80"}
    )
    assert done.returncode == 1, done.stderr
    lines = done.stdout.splitlines()
    # The report's path is a name, never broken (it runs as long as the test's folder).
    assert lines[-1] == f"  report: {failures / 'fast-lockstep' / 'report.html'}"
    assert max(map(len, lines[:-1])) <= 80, done.stdout
    # Each divergence starts a line; its continuation lines are indented deeper.
    starts = [i for i, line in enumerate(lines) if line.startswith("  /fusion/odometry t=")]
    end = next(i for i, line in enumerate(lines) if line.startswith("  lockstep ("))
    assert starts and starts[-1] < end
    shown = [
        " ".join(part.strip() for part in lines[start:stop])
        for start, stop in zip(starts, [*starts[1:], end], strict=True)
    ]
    report = json.loads((failures / "fast-lockstep" / "report.json").read_text())
    texts = {d["text"] for topic in report["topics"] for d in topic["divergences"]}
    assert set(shown) <= texts
