"""``bagkit stats summary`` over many bags: a local cluster, started by a real ``bagkit``
process, gives the in-process output; Ctrl-C stops it with exit 130 and leaves no process
behind. Runs that start no cluster run in the test's process, but for one error line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import psutil
import pytest
from bagkit_runs import bagkit_in_process
from test_fleet_stats import RELATIVE

from bagkit.fleet.cluster import WorkRate, fleet_client
from bagkit.fleet.errors import FleetError

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _cluster_summary(*args: str) -> tuple[dict[str, object], str]:
    """In a ``bagkit`` process of its own: the cluster it starts is that process's to stop."""
    done = subprocess.run(
        [BAGKIT, "stats", "summary", *args, "--format", "json"],
        capture_output=True,
        text=True,
        timeout=180,
        check=True,
    )
    return json.loads(done.stdout), done.stderr


def _summary(*args: str) -> tuple[dict[str, object], str]:
    done = bagkit_in_process(["stats", "summary", *args, "--format", "json"], Path.cwd())
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout), done.stderr


def test_workers_give_the_in_process_output(fleet_dir: Path) -> None:
    local, notes = _cluster_summary(str(fleet_dir), "--workers", "2")
    here, _ = _summary(str(fleet_dir), "--workers", "0")
    assert "local Dask cluster of 2 workers, dashboard http://127.0.0.1:" in notes
    assert local["bags"] == here["bags"] and len(local["bags"]) == 6  # type: ignore[arg-type]
    for mine, theirs in zip(local["topics"], here["topics"], strict=True):  # type: ignore[call-overload]
        assert mine["count"] == theirs["count"]
        for f, g in zip(mine["fields"], theirs["fields"], strict=True):
            assert (f["count"], f["min"], f["max"]) == (g["count"], g["min"], g["max"])
            for key in ("mean", "std"):
                if isinstance(g[key], float):
                    assert abs(f[key] - g[key]) <= RELATIVE * abs(g[key])
                else:
                    assert f[key] == g[key]


def test_one_bag_runs_in_process(fleet_bags: list[Path]) -> None:
    _, notes = _summary(str(fleet_bags[0]))
    assert "Dask" not in notes


def test_small_bags_run_in_process_by_default(fleet_dir: Path) -> None:
    # Six bags of a few kB: a cluster's start would cost more than the work.
    default, notes = _summary(str(fleet_dir))
    here, _ = _summary(str(fleet_dir), "--workers", "0")
    assert "Dask" not in notes
    assert default == here


def test_ctrl_c_stops_the_local_cluster(fleet_bags: list[Path], tmp_path: Path) -> None:
    for i in range(300):  # enough tasks to be interrupted in the middle
        (tmp_path / f"bag_{i}").symlink_to(fleet_bags[i % len(fleet_bags)])
    proc = subprocess.Popen(
        [BAGKIT, "stats", "summary", str(tmp_path), "--workers", "2", "--format", "json"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        # As from a shell: a test runner's worker may ignore SIGINT, and children inherit that.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.default_int_handler),  # noqa: PLW1509
    )
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        assert "local Dask cluster" in line, line
        children = psutil.Process(proc.pid).children(recursive=True)
        assert len(children) >= 2
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: to the whole group
        rest = proc.stderr.read()
        assert proc.wait(timeout=60) == 130, rest
        assert "interrupted" in rest
        assert "Traceback" not in rest, rest
        _, alive = psutil.wait_procs(children, timeout=10)
        assert not alive, f"left running: {[p.pid for p in alive]}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _error_line(*args: str, env: dict[str, str] | None = None, in_process: bool = False) -> str:
    """``bagkit stats summary ARGS``, which must end with one error line and exit 2."""
    command = ["stats", "summary", *args]
    if in_process:
        done = bagkit_in_process(list(command), Path.cwd())
    else:
        done = subprocess.run(
            [BAGKIT, *command], capture_output=True, text=True, timeout=120, check=False, env=env
        )
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    return done.stderr.strip()


def test_unreachable_scheduler_is_one_error_line(fleet_bags: list[Path]) -> None:
    line = _error_line(
        *map(str, fleet_bags[:2]),
        "--scheduler",
        "tcp://127.0.0.1:9",
        env={**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"},
    )
    assert line.startswith("error: cannot reach the Dask scheduler at tcp://127.0.0.1:9")


def test_a_mistyped_worker_count_starts_no_process(fleet_bags: list[Path]) -> None:
    line = _error_line(*map(str, fleet_bags[:2]), "--workers", "100000", in_process=True)
    assert line.startswith("error: --workers 100000: a local cluster runs at most 4")
    assert line.endswith("; for more, start a cluster and give --scheduler")
    many = fleet_client(workers=100_000, scheduler=None, bags=2, size_bytes=1, rate=WorkRate(1, 1))
    with pytest.raises(FleetError) as raised, many:  # the library names its own field
        pass
    assert raised.value.field == "workers" and "--" not in str(raised.value)


def test_no_bag_in_the_inputs_is_one_error_line(tmp_path: Path) -> None:
    assert _error_line(str(tmp_path)) == f"error: no bag in {tmp_path}"
