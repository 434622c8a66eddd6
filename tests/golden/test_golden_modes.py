"""``golden check --mode``: a fixture is checked only in the modes its spec lists, as the pytest
plugin runs it, and the CLI says which fixtures it left out."""

from __future__ import annotations

import shutil
from pathlib import Path

import yaml

from tests.bagkit_runs import bagkit_in_process

REPO = Path(__file__).resolve().parents[2]


def _fixture(tmp_path: Path, name: str, modes: list[str]) -> Path:
    """A copy of the repository's fast fixture named ``name``, held to ``modes``."""
    folder = tmp_path / name
    shutil.copytree(REPO / "fixtures" / "fast", folder)
    spec = yaml.safe_load((folder / "spec.yaml").read_text())
    (folder / "spec.yaml").write_text(yaml.safe_dump({**spec, "modes": modes}))
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
