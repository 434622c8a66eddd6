""".ci/run's own logic (order, exit codes, the background venv builds), with make stubbed."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from pathlib import Path

from waiting import running, wait_for

REPO = Path(__file__).resolve().parents[1]
LEGS = ["PYV=3.10 RESOLUTION=lowest-direct", "PYV=3.12", "PYV=3.13"]

# Records each call; `make $FAIL_MAKE` exits 2; `make $SLOW_MAKE` becomes a long sleep whose pid
# it leaves behind, to show who stops it.
MAKE = """#!/usr/bin/env bash
echo "$*" >> "$CALLS"
echo "make $* ran"
if [ "$*" = "${SLOW_MAKE:-}" ]; then echo $$ > "$SLOW_PID"; exec sleep 60; fi
if [ "$*" = "${FAIL_MAKE:-}" ]; then
    # Fails only once the slow step runs, so that there is a build to stop.
    while [ -n "${SLOW_MAKE:-}" ] && [ ! -s "$SLOW_PID" ]; do sleep 0.01; done
    exit 2
fi
"""


def run_ci(tmp_path: Path, **env: str) -> tuple[subprocess.CompletedProcess[str], list[str]]:
    checkout = tmp_path / "checkout"
    (checkout / ".ci").mkdir(parents=True)
    shutil.copy(REPO / ".ci" / "run", checkout / ".ci" / "run")
    stubs = tmp_path / "stubs"
    stubs.mkdir()
    for name, text in {"make": MAKE, "chromium": "#!/bin/sh\n"}.items():
        (stubs / name).write_text(text)
        (stubs / name).chmod(0o755)
    calls = tmp_path / "calls"
    environ = {
        **os.environ,
        "PATH": f"{stubs}{os.pathsep}{os.environ['PATH']}",
        "CALLS": str(calls),
        "SLOW_PID": str(tmp_path / "slow.pid"),
        **env,
    }
    done = subprocess.run(
        ["bash", str(checkout / ".ci" / "run")],
        env=environ,
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    return done, calls.read_text().splitlines()


def test_a_passing_run_exits_0_after_every_step_in_order(tmp_path: Path) -> None:
    done, calls = run_ci(tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert calls[0] == "lint"
    assert [c for c in calls if c.startswith("venv-py")] == [f"venv-py {leg}" for leg in LEGS]
    assert calls[-3:] == [f"test-py {leg}" for leg in LEGS]
    # make test ran before the legs, beside the builds; their log is printed after it.
    assert calls.index("test") < len(calls) - 3
    assert f"make venv-py {LEGS[-1]} ran" in done.stdout


def test_a_failed_venv_build_is_one_error_and_no_leg_runs(tmp_path: Path) -> None:
    done, calls = run_ci(tmp_path, FAIL_MAKE=f"venv-py {LEGS[1]}")
    assert done.returncode == 2
    assert done.stderr.splitlines() == ["error: the venv of another Python failed"]
    assert f"make venv-py {LEGS[1]} ran" in done.stdout
    assert f"venv-py {LEGS[2]}" not in calls
    assert not [c for c in calls if c.startswith("test-py")]


def test_a_failed_make_test_stops_the_builds_and_keeps_its_code(tmp_path: Path) -> None:
    done, calls = run_ci(tmp_path, FAIL_MAKE="test", SLOW_MAKE=f"venv-py {LEGS[0]}")
    assert done.returncode == 2
    assert not [c for c in calls if c.startswith("test-py")]
    builder = int((tmp_path / "slow.pid").read_text())
    try:
        wait_for(lambda: not running(builder), what="the venv build to stop with .ci/run")
    finally:
        if running(builder):
            os.kill(builder, signal.SIGKILL)
