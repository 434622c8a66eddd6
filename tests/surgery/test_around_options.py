"""--around's options: the library's errors name their fields, the CLI its flags."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bagkit.errors import OptionError
from bagkit.regression.add import AddOptions, add_fixture
from bagkit.selection.query import Query
from bagkit.surgery.around import Around, cut_around
from bagkit.surgery.select import Selection

BAG = Path(__file__).resolve().parents[2] / "fixtures" / "faults" / "golden"
TRIGGER = "/alerts: status[*].level >= 2"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))


@pytest.mark.parametrize("field", ["before_ns", "after_ns", "gap_ns"])
def test_a_negative_margin_names_its_field(field: str) -> None:
    with pytest.raises(OptionError, match=f"^{field}: must be 0 or more, got -1$") as error:
        Around.create(TRIGGER, **{field: -1})
    assert error.value.field == field


def test_a_span_beside_around_names_its_field(tmp_path: Path) -> None:
    span = Query.create(start="5").span
    with pytest.raises(OptionError) as cut:
        cut_around(BAG, tmp_path / "cuts", Around.create(TRIGGER), Selection(span=span))
    with pytest.raises(OptionError) as added:
        add_fixture(tmp_path / "fx", AddOptions(BAG, span, around=TRIGGER))
    assert (cut.value.field, added.value.field) == ("selection.span", "span")
    assert not (tmp_path / "cuts").exists() and not (tmp_path / "fx").exists()


@pytest.mark.parametrize("command", [["filter", BAG, "-o"], ["golden", "add"]])
def test_the_cli_names_the_flags(command: list[str | Path], tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = [*command, out] if command[0] == "filter" else [*command, out, "--from", BAG]
    result = subprocess.run(
        [BAGKIT, *map(str, args), "--around", TRIGGER, "--start", "5"],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert result.returncode == 2 and not out.exists()
    assert result.stderr.splitlines() == [
        "error: --start/--end with --around: must be empty (each episode of the trigger sets "
        "its window)"
    ]
