"""``bagkit info DIR`` of a folder of bags (snapshot-mode output, a fleet folder): one line per
bag and the totals, checked against the bag reader (subprocesses of the CLI)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from bagkit.bag import BagReader

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"


def _folder(tmp_path: Path) -> tuple[Path, dict[str, Path]]:
    root = tmp_path / "blackbox"
    bags = {
        "day1/snapshot_1": FIXTURES / "faults" / "golden",
        "snapshot_2": FIXTURES / "nominal" / "golden",
    }
    for name, source in bags.items():
        shutil.copytree(source, root / name)
    shutil.copy(FIXTURES / "fast" / "golden" / "golden_0.mcap", root / "loose.mcap")
    bags["loose.mcap"] = FIXTURES / "fast" / "golden" / "golden_0.mcap"
    (root / "notes.txt").write_text("not a bag\n")
    return root, bags


def _counts(bag: Path) -> tuple[int, int]:
    with BagReader(bag) as reader:
        return reader.message_count, reader.end_ns - reader.start_ns


def test_info_of_a_folder_lists_its_bags_with_totals(tmp_path: Path) -> None:
    root, bags = _folder(tmp_path)
    result = subprocess.run(
        [BAGKIT, "info", str(root), "--format", "json"], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    found = json.loads(result.stdout)
    listed = {str(Path(b["path"]).relative_to(root)): b for b in found["bags"]}
    assert sorted(listed) == sorted(bags)
    for name, source in bags.items():
        count, span_ns = _counts(source)
        assert listed[name]["message_count"] == count
        assert listed[name]["duration_s"] == span_ns / 1e9
    assert found["bag_count"] == 3
    assert found["message_count"] == sum(_counts(s)[0] for s in bags.values())
    assert found["unread"] == {}


def test_info_of_a_folder_prints_one_line_per_bag_at_80_columns(tmp_path: Path) -> None:
    root, bags = _folder(tmp_path)
    result = subprocess.run(
        [BAGKIT, "info", str(root)],
        capture_output=True,
        text=True,
        check=False,
        env={"COLUMNS": "80", "PATH": ""},
    )
    assert result.returncode == 0, result.stderr
    rows = {line.split()[0]: line.split() for line in result.stdout.splitlines()[1:] if line}
    for name, source in bags.items():
        assert rows[name][1] == f"{_counts(source)[0]:,}"
    total = sum(_counts(s)[0] for s in bags.values())
    assert rows["total"][1] == f"{total:,}"
    assert result.stdout.splitlines()[0] == f"{root}: 3 bags"
    assert max(len(line) for line in result.stdout.splitlines()[1:]) <= 80


def test_info_of_a_folder_without_bags_is_still_not_a_bag(tmp_path: Path) -> None:
    result = subprocess.run(
        [BAGKIT, "info", str(tmp_path)], capture_output=True, text=True, check=False
    )
    assert result.returncode == 2
    assert result.stderr.startswith(f"error: {tmp_path}: not a bag")


def test_a_bag_of_the_folder_that_cannot_be_read_is_the_fleet_rule(tmp_path: Path) -> None:
    """As every many-bag command (docs/fleet.md, "Bags that cannot be read"): the others
    listed, a warning naming the bag once, then one error line and exit 2."""
    root, bags = _folder(tmp_path)
    broken = root / "broken.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 64)
    for output in ("table", "json"):
        result = subprocess.run(
            [BAGKIT, "info", str(root), "--format", output],
            capture_output=True,
            text=True,
            check=False,
        )
        assert result.returncode == 2, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 2 and lines[0].startswith(f"warning: {broken}: not read: ")
        assert lines[0].count(str(broken)) == 1
        assert lines[1] == f"error: 1 of {len(bags) + 1} bags could not be read"
    assert list(json.loads(result.stdout)["unread"]) == [str(broken)]
