"""``pip install bagkit``, as a user does it: a wheel of this checkout in a fresh venv, no extra.

The offline commands must work there and say what the full install (this test's own
environment) says; no ROS wheel, no Dask, no plotly or bokeh gets installed; a command that
needs an extra prints one line naming the install command and exits 2.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from wheel_build import build_wheel, uv

from bagkit.bag import BagReader

pytestmark = pytest.mark.install

REPO = Path(__file__).resolve().parents[2]
LOCK = REPO / "requirements" / "lock.txt"
GOLDEN = REPO / "fixtures" / "nominal" / "golden"
OTHER_GOLDEN = REPO / "fixtures" / "faults" / "golden"
FULL_BAGKIT = Path(sys.executable).with_name("bagkit")
# What only the extras bring (distribution names, normalized).
EXTRA_ONLY = {"dask", "distributed", "plotly", "bokeh"}
LEAKS = {"PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "AMENT_PREFIX_PATH"}


@dataclass(frozen=True)
class PlainInstall:
    wheel: Path
    python: Path

    def bagkit(self, *args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
        return run([self.python.with_name("bagkit"), *args], cwd=cwd, bytecode=True)


def run(
    args: list[str | Path], cwd: Path = REPO, *, bytecode: bool = False
) -> subprocess.CompletedProcess[str]:
    """``args`` without this environment's Python setup or a sourced ROS install; ``bytecode``:
    Python may write its bytecode caches (PYTHONDONTWRITEBYTECODE unset), as in a user's venv
    where pip compiled them at install (uv does not: under PYTHONDONTWRITEBYTECODE, as in CI,
    each command of the plain venv would compile numpy, pandas and pyarrow again)."""
    leaks = LEAKS | {"PYTHONDONTWRITEBYTECODE"} if bytecode else LEAKS
    env = {k: v for k, v in os.environ.items() if k not in leaks}
    return subprocess.run(
        [str(a) for a in args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )


def counts(bag: Path) -> Counter[str]:
    """Messages per topic, read in this process."""
    with BagReader(bag) as reader:
        return Counter(message.topic for message in reader.messages())


def install(wheel: Path, python: Path) -> None:
    """``wheel`` into ``python``'s venv, without extras; the lock as constraints: the versions
    CI tests, from the package cache."""
    tool = uv()
    command = (
        [tool, "pip", "install", "--quiet", "--python", python]
        if tool
        else [python, "-m", "pip", "install", "--quiet"]
    )
    installed = run([*command, wheel, "-c", LOCK])
    assert installed.returncode == 0, installed.stderr


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> PlainInstall:
    """bagkit's wheel, built from this checkout, installed without extras into a fresh venv."""
    root = tmp_path_factory.mktemp("plain")
    venv = root / "venv"
    assert run([sys.executable, "-m", "venv", venv]).returncode == 0
    python = venv / "bin" / "python"
    wheel = build_wheel(REPO, ["pyproject.toml", "setup.py", "README.md", "bagkit"], root)
    install(wheel, python)
    return PlainInstall(wheel, python)


def test_the_wheel_holds_bagkit_alone(plain: PlainInstall) -> None:
    with zipfile.ZipFile(plain.wheel) as wheel:
        names = wheel.namelist()
        entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
        scripts = wheel.read(entry_points).decode()
    assert {n.split("/")[0] for n in names} == {"bagkit", entry_points.split("/")[0]}
    assert any(n.startswith("bagkit/ros/record/_take.") and n.endswith(".so") for n in names)
    assert "bagkit/py.typed" in names
    assert "bagkit = bagkit.cli.launch:run" in scripts
    assert "bagkit = bagkit.pytest_plugin" in scripts  # the pytest plugin
    assert "fusion" not in scripts


def test_no_ros_dask_or_browser_plotting_is_installed(plain: PlainInstall) -> None:
    listed = run([plain.python, "-m", "pip", "list", "--format", "json"], bytecode=True)
    names = {d["name"].lower().replace("_", "-") for d in json.loads(listed.stdout)}
    assert "bagkit" in names
    assert not {n for n in names if n.startswith("ros-")}
    assert not names & EXTRA_ONLY
    imports = run([plain.python, "-c", "import importlib.util as u; print(u.find_spec('rclpy'))"])
    assert imports.stdout.strip() == "None"


@pytest.mark.parametrize(
    ("args", "reference"),
    [
        (("info", "--format", "json", GOLDEN), ()),
        (("stats", "summary", "--format", "json", GOLDEN), ()),
        # Several bags: by default on Dask; without the fleet extra, in this process (the full
        # install's Dask run sums in another order: compared with its in-process run).
        (("stats", "summary", "--format", "json", GOLDEN, OTHER_GOLDEN), ("--workers", "0")),
        (("echo", GOLDEN, "/gps/fix", "-n", "3", "--format", "json"), ()),
        (("compare", "--format", "json", GOLDEN, GOLDEN), ()),
    ],
    ids=["info", "stats", "stats-two-bags", "echo", "compare"],
)
def test_offline_commands_say_what_the_full_install_says(
    plain: PlainInstall, args: tuple[str | Path, ...], reference: tuple[str, ...], tmp_path: Path
) -> None:
    got = plain.bagkit(*args, cwd=tmp_path)
    assert got.returncode == 0, got.stderr
    assert got.stdout == run([FULL_BAGKIT, *args, *reference], cwd=tmp_path).stdout
    assert got.stdout.strip()


def test_export_filter_and_compare_of_the_result(plain: PlainInstall, tmp_path: Path) -> None:
    imu_count = counts(GOLDEN)["/imu/data"]
    exported = plain.bagkit("export", GOLDEN, "-t", "/imu/data", "-o", "imu.parquet", cwd=tmp_path)
    assert exported.returncode == 0, exported.stderr
    assert pq.read_table(tmp_path / "imu.parquet").num_rows == imu_count

    kept = plain.bagkit("filter", GOLDEN, "-o", "imu", "--topics", "/imu/data", cwd=tmp_path)
    assert kept.returncode == 0, kept.stderr
    assert counts(tmp_path / "imu") == {"/imu/data": imu_count}
    other = plain.bagkit(
        "filter", OTHER_GOLDEN, "-o", "other", "--topics", "/imu/data", cwd=tmp_path
    )
    assert other.returncode == 0, other.stderr
    # Another flight's IMU samples: a difference, exit 1; the same ones: none, exit 0.
    assert plain.bagkit("compare", "imu", "other", cwd=tmp_path).returncode == 1
    assert plain.bagkit("compare", "imu", GOLDEN, cwd=tmp_path).returncode == 0
    # The golden's other topics are absent from the filtered bag: a broken candidate, exit 1.
    assert plain.bagkit("compare", GOLDEN, "imu", cwd=tmp_path).returncode == 1
    assert plain.bagkit("compare", GOLDEN, "imu", "-t", "/imu/data", cwd=tmp_path).returncode == 0


def test_png_plot_needs_no_extra(plain: PlainInstall, tmp_path: Path) -> None:
    plotted = plain.bagkit("plot", GOLDEN, "/temperature:temperature", "-o", "t.png", cwd=tmp_path)
    assert plotted.returncode == 0, plotted.stderr
    assert (tmp_path / "t.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ("record", "/imu/data"),
            "error: bagkit record needs ROS 2 (rclpy): pip install 'bagkit[ros]' or source "
            "your ROS 2 Jazzy install",
        ),
        (
            ("replay", GOLDEN),
            "error: bagkit replay needs ROS 2 (rclpy): pip install 'bagkit[ros]' or source "
            "your ROS 2 Jazzy install",
        ),
        (
            ("stats", "summary", "--workers", "2", GOLDEN, OTHER_GOLDEN),
            "error: running on Dask (--workers, --scheduler) needs Dask (dask, distributed): "
            "pip install 'bagkit[fleet]'",
        ),
        (
            ("plot", GOLDEN, "/temperature:temperature", "-o", "t.html"),
            "error: an HTML plot needs plotly: pip install 'bagkit[plot]'",
        ),
    ],
    ids=["record", "replay", "workers", "html-plot"],
)
def test_a_missing_extra_is_one_line_naming_the_install_command(
    plain: PlainInstall, args: tuple[str | Path, ...], line: str, tmp_path: Path
) -> None:
    got = plain.bagkit(*args, cwd=tmp_path)
    assert (got.returncode, got.stderr.splitlines()) == (2, [line])
    assert not list(tmp_path.iterdir())
