"""``bagkit export`` over many bags: a local cluster writes the files one process writes, each
bag into its own folder; a bag that cannot be read is reported and the others are exported."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from distributed import Client

from bagkit import read_dataframe
from bagkit.fleet.errors import FleetError
from bagkit.fleet.export import bag_folders, export_fleet
from bagkit.selection.query import Query

IMU = Query.create("/imu/data")

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _tables(root: Path) -> dict[str, pd.DataFrame]:
    return {
        str(path.relative_to(root)): pd.read_parquet(path)
        for path in sorted(root.rglob("*.parquet"))
    }


def test_cluster_writes_what_one_process_writes(
    client: Client, fleet_bags: list[Path], tmp_path: Path
) -> None:
    here = export_fleet(fleet_bags, tmp_path / "here", query=IMU)
    there = export_fleet(fleet_bags, tmp_path / "there", query=IMU, client=client)
    assert [r.error for r in here + there] == [None] * (2 * len(fleet_bags))
    mine, theirs = _tables(tmp_path / "here"), _tables(tmp_path / "there")
    assert sorted(mine) == sorted(theirs) and len(mine) == len(fleet_bags)
    for name, frame in mine.items():
        pd.testing.assert_frame_equal(frame, theirs[name])


def test_each_bag_exports_as_it_would_alone(fleet_bags: list[Path], tmp_path: Path) -> None:
    results = export_fleet(fleet_bags[:2], tmp_path, query=Query.create("/imu/data", ["linear_*"]))
    for result in results:
        written = pd.read_parquet(result.out / "imu" / "data.parquet")
        alone = read_dataframe(result.bag, "/imu/data", fields=["linear_*"])
        assert len(written) == len(alone) > 0
        assert (
            written["linear_acceleration.z"].to_numpy() == alone["linear_acceleration.z"].to_numpy()
        ).all()


def test_folders_keep_the_bags_relative_paths(tmp_path: Path) -> None:
    for name in ("day1/bag_0", "day2/bag_0"):
        (tmp_path / name).mkdir(parents=True)
    (tmp_path / "day1" / "loose.mcap").write_bytes(b"")
    bags = [tmp_path / "day1/bag_0", tmp_path / "day2/bag_0", tmp_path / "day1/loose.mcap"]
    out = Path("/out")
    assert bag_folders(bags, out) == [out / "day1/bag_0", out / "day2/bag_0", out / "day1/loose"]
    (tmp_path / "day1" / "loose").mkdir()
    with pytest.raises(FleetError, match="rename one"):
        bag_folders([tmp_path / "day1/loose", tmp_path / "day1/loose.mcap"], out)


def test_cli_reports_an_unreadable_bag_and_exports_the_rest(
    fleet_bags: list[Path], tmp_path: Path
) -> None:
    bad = tmp_path / "bags" / "broken.mcap"
    bad.parent.mkdir()
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 64)
    listing = tmp_path / "bags.txt"
    listing.write_text("\n".join([str(fleet_bags[0]), str(bad), str(fleet_bags[1])]) + "\n")
    done = subprocess.run(
        [BAGKIT, "export", str(listing), "-o", str(tmp_path / "out"), "--workers", "2"],
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )
    assert done.returncode == 2, done.stderr  # docs/fleet.md, "Bags that cannot be read"
    assert "Traceback" not in done.stderr
    assert "local Dask cluster of 2 workers" in done.stderr
    lost = [line for line in done.stderr.splitlines() if "not exported" in line]
    assert len(lost) == 1 and lost[0].startswith(f"warning: {bad}: not exported: "), lost
    assert done.stderr.strip().splitlines()[-1] == "error: 1 of 3 bags could not be exported"
    exported = sorted(p.parent.parent.name for p in (tmp_path / "out").rglob("data.parquet"))
    assert exported == sorted(b.name for b in fleet_bags[:2])


def test_cli_one_bag_keeps_the_single_bag_layout(fleet_bags: list[Path], tmp_path: Path) -> None:
    done = subprocess.run(
        [BAGKIT, "export", str(fleet_bags[0]), "-t", "/imu/data", "-o", str(tmp_path / "imu.csv")],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "Dask" not in done.stderr
    assert len(pd.read_csv(tmp_path / "imu.csv")) == len(read_dataframe(fleet_bags[0], "/imu/data"))
