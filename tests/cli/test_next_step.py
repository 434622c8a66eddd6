"""From a finding to the next step (subprocesses): find's offsets taken as printed by filter
and golden add; several bags' service latencies each named by their bag."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from bagkit.bag import BagReader

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
BAG = Path(__file__).resolve().parents[2] / "fixtures" / "faults" / "golden"
SERVICES = "rosbag2_tests/resources/mcap/bag_with_topics_and_service_events"
WHEN = "/alerts: status[*].level >= 2"


def _bagkit(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, *map(str, args)], capture_output=True, text=True, timeout=300, cwd=cwd, check=False
    )


def test_finds_offsets_cut_each_episode_whole_in_filter_and_golden_add(tmp_path: Path) -> None:
    found = _bagkit("find", BAG, "--when", WHEN, "--format", "json", cwd=tmp_path)
    assert found.returncode == 0, found.stderr
    episodes = json.loads(found.stdout)
    assert episodes
    for n, episode in enumerate(episodes[:2]):
        first, last = str(episode["start_offset_s"]), str(episode["end_offset_s"])
        assert len(first.partition(".")[2]) <= 3 and len(last.partition(".")[2]) <= 3  # ms
        cut = _bagkit("filter", BAG, "-o", f"cut{n}", "--topics", "/alerts", "--no-latched",
                      "--start", first, "--end", last, cwd=tmp_path)  # fmt: skip
        assert cut.returncode == 0, cut.stderr
        with BagReader(tmp_path / f"cut{n}") as reader:
            times = [m.log_time for m in reader.messages(["/alerts"])]
        assert episode["start_ns"] in times and episode["end_ns"] in times
    first, last = str(episodes[0]["start_offset_s"]), str(episodes[0]["end_offset_s"])
    added = _bagkit("golden", "add", "fx", "--from", BAG, "--start", first, "--end", last,
                    cwd=tmp_path)  # fmt: skip
    assert added.returncode == 0, added.stderr
    with BagReader(tmp_path / "fx" / "golden") as reader:
        assert episodes[0]["start_ns"] in [m.log_time for m in reader.messages(["/alerts"])]


def test_per_bag_latency_lines_name_their_bag(interop_dir: Path, tmp_path: Path) -> None:
    for name in ("first", "second"):
        shutil.copytree(interop_dir / SERVICES, tmp_path / name)
    shown = _bagkit("stats", "summary", "first", "second", "-t", "/test_service1", cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    lines = [line for line in shown.stdout.splitlines() if "latency:" in line]
    assert [line.split(":")[0] for line in lines] == ["first", "second"]
