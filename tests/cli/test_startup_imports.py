"""What each quick command imports at start (issue 36, item 2): ``-X importtime`` of the real
console script, a heavy module named here fails the test (start-up time itself is measured by
``benchmarks startup``, not asserted)."""

from __future__ import annotations

import importlib
import inspect
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
# A bag with services (std_srvs/srv/Trigger events) beside fixed-layout sensor topics.
SERVICES_BAG = FIXTURES / "fast" / "golden"
PLAIN_BAG = FIXTURES / "nominal" / "golden"
# check's contract: presence, type, rate, gap and value assertions (the ones read in bulk).
CONTRACT = FIXTURES / "fast" / "health.yaml"

# No quick command needs these: data frames, Dask, plots, ROS, .db3 bags, terminal styling for
# piped output, option validation; on a local bag, threads and logging (a local cluster's, bags
# in storage read on threads) and temporary files (copies of bags in storage or file-compressed);
# lz4 and ros2idl definitions (the fixtures have zstd chunks and .msg texts); the mcap
# package's record dataclasses (bagkit reads into its own records; the package's encode).
HEAVY = frozenset(
    {"pandas", "pyarrow", "dask", "distributed", "matplotlib", "rclpy", "sqlite3", "rich"}
    | {"pydantic", "scipy", "logging", "concurrent", "tempfile", "lz4", "bagkit.decode.idl"}
    | {"mcap.records"}
)
# info reads summaries and indexes, and service events by their fixed header (the message
# index ordered without numpy): no decoder, no numpy.
NO_DECODER = frozenset({"rosbags", "bagkit.decode"})
# Decoding needs nothing of rosbags (its type system, code generation and serializers, OpenSSL's
# hashlib): only encoding (migrate) and other formats' files do.
NO_ROSBAGS = frozenset({"rosbags", "hashlib", "_hashlib"})
# A topic's messages or a bag without services: none of the service modules.
NO_SERVICES = frozenset(
    {"bagkit.data.services", "bagkit.data.service_summaries", "bagkit.bag.service_calls"}
)
# Without --where, no condition language and no matcher of conditions.
NO_CONDITION = frozenset({"bagkit.selection.conditions", "bagkit.decode.matcher"})
# echo without --fields decodes whole messages: no bulk or direct reader (numpy layouts of
# leaves).
NO_LEAVES = frozenset({"bagkit.decode.bulk", "bagkit.decode.direct"})
# A whole message printed is read into Python's numbers: no numpy (nor the interval algebra of
# a condition over time).
NO_ARRAYS = frozenset({"numpy", "bagkit.selection.intervals"})

# The decoding commands print tables: no `bagkit info` records (rates are bagkit.bag.rates'),
# nor its compression in words, no csv (stats --format csv only), no shlex (the commands
# printed for a failed check only).
NOT_PRINTED = frozenset({"bagkit.bag.info", "bagkit.bag.compression_words", "csv", "shlex"})

# One local bag runs in this process: the optional extras (Dask's) are not looked for.
NO_EXTRAS = frozenset({"bagkit.extras"})

# What `bagkit record` selects (services and actions asked for) is no reader's business.
NOT_RECORDING = frozenset({"bagkit.selection.record_selection"})

# The latched state at a late start (play --start-offset, filter --start) is found then.
NO_LATE_START = frozenset({"bagkit.bag.mcapio.latest"})

DECODING = HEAVY | NO_ROSBAGS | NOT_PRINTED | NO_EXTRAS | NOT_RECORDING | NO_LATE_START
CASES = {
    "info": (
        ["info", str(PLAIN_BAG)],
        HEAVY | NO_DECODER | NOT_RECORDING | NO_LATE_START | {"numpy"},
    ),
    "info with services": (
        ["info", str(SERVICES_BAG)],
        HEAVY | NO_DECODER | NOT_RECORDING | NO_LATE_START | {"numpy"},
    ),
    "echo": (
        ["echo", str(SERVICES_BAG), "/imu/data", "-n", "1"],
        DECODING | NO_CONDITION | NO_LEAVES | NO_SERVICES | NO_ARRAYS,
    ),
    "stats": (["stats", "summary", str(SERVICES_BAG)], DECODING | NO_CONDITION),
    "stats without services": (
        ["stats", "summary", str(PLAIN_BAG), "--format", "json"],
        DECODING | NO_CONDITION | NO_SERVICES,
    ),
    "find": (
        ["find", str(SERVICES_BAG), "--when", "/imu/data: linear_acceleration.z < 5"],
        DECODING,
    ),
    # A contract is checked without the statistics that --suggest makes one from.
    "check": (["check", str(SERVICES_BAG), "--spec", str(CONTRACT)], DECODING | {"bagkit.stats"}),
}


def imported_at_start(args: list[str], exit_code: int = 0) -> tuple[set[str], str]:
    """The modules ``bagkit ARGS`` imports (by ``-X importtime``), and its stdout."""
    done = subprocess.run(
        [sys.executable, "-X", "importtime", BAGKIT, *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == exit_code, done.stderr[-2000:]
    modules = {
        line.rsplit("|", 1)[1].strip()
        for line in done.stderr.splitlines()
        if line.startswith("import time:") and "|" in line
    }
    return modules, done.stdout


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_quick_command_imports_no_heavy_module(case: str) -> None:
    args, forbidden = CASES[case]
    modules, stdout = imported_at_start(args)
    assert stdout  # the command did its work
    assert "bagkit.bag.reader" in modules  # and the check sees what ran
    heavy = sorted(n for n in modules if any(n == f or n.startswith(f"{f}.") for f in forbidden))
    assert not heavy, f"bagkit {' '.join(args)} imports {heavy}"


def test_recover_copying_every_chunk_imports_no_numpy(tmp_path: Path) -> None:
    # A bag cut short: every whole chunk is copied as stored, its CRC checked, its Message
    # Index records taken as stored; numpy is for the chunks that must be opened, rich for a
    # terminal.
    (stored,) = PLAIN_BAG.glob("*.mcap")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(stored.read_bytes()[: stored.stat().st_size * 3 // 4])
    out = tmp_path / "recovered"
    modules, stdout = imported_at_start(["recover", str(cut), "-o", str(out)], exit_code=3)
    assert "copied as stored" in stdout
    assert "bagkit.surgery.copy" in modules
    assert not {"numpy", "bagkit.surgery.runs", "bagkit.decode", "rich"} & modules
    # The fixture's one chunk lies before the cut: every message is recovered.
    counts = [
        json.loads(bagkit_in_process(["info", str(bag), "--format", "json"]).stdout)
        for bag in (out, PLAIN_BAG)
    ]
    assert counts[0]["message_count"] == counts[1]["message_count"] > 0


def _threads_after_numpy(environment: dict[str, str]) -> int:
    """Threads of a process that ran the console script's entry (``--version``) and then
    imported numpy (OpenBLAS starts its threads then)."""
    probe = (
        "import os, sys\n"
        "from bagkit.cli import launch\n"
        "sys.argv = ['bagkit', '--version']\n"
        "try:\n    launch.run()\nexcept SystemExit:\n    pass\n"
        "import numpy\n"
        "print(len(os.listdir('/proc/self/task')))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
        env=environment,
    )
    return int(done.stdout.split()[-1])


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="threads counted in /proc")
def test_the_command_runs_numpy_on_one_blas_thread() -> None:
    environment = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    assert _threads_after_numpy(environment) == 1
    # A user's own setting is kept: with two BLAS threads asked for, numpy starts a second
    # one (on a machine of one core OpenBLAS starts none, whatever is asked).
    if (os.cpu_count() or 1) > 1:
        assert _threads_after_numpy({**environment, "OPENBLAS_NUM_THREADS": "2"}) == 2


@pytest.mark.parametrize("args", [["--version"], ["stats", "summary", "no-such-bag"]])
def test_the_command_leaves_the_collectors_last_pass_nothing(args: list[str]) -> None:
    """Objects alive when a command ends (successful or not) are frozen: the interpreter's
    collection at exit skips them."""
    probe = (
        "import atexit, gc, sys\n"
        "from bagkit.cli import launch\n"
        "atexit.register(lambda: print('frozen', gc.get_freeze_count()))\n"
        f"sys.argv = ['bagkit', *{args!r}]\n"
        "launch.run()\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == (0 if args == ["--version"] else 2), done.stderr
    frozen = int(done.stdout.split("frozen")[-1])
    assert frozen > 10_000  # numpy's, typer's and bagkit's modules, not a handful


@pytest.mark.parametrize(
    ("module", "command"),
    [
        *(("echo", "echo"), ("stats", "summary"), ("find", "find"), ("check", "check")),
        # The callbacks every command or several run: the top level's, --distro's.
        *(("main", "main"), ("main", "_version_callback"), ("selection_options", "_use_distro")),
    ],
)
def test_a_quick_command_has_its_annotations_as_objects(module: str, command: str) -> None:
    """typer reads a command's (and a callback's) parameters at every start and compiles each
    annotation written as a string (``from __future__ import annotations``) twice."""
    function = getattr(importlib.import_module(f"bagkit.cli.{module}"), command)
    strings = [n for n, a in inspect.get_annotations(function).items() if isinstance(a, str)]
    assert not strings, f"bagkit.cli.{module}.{command}: annotations as strings: {strings}"


# Records made at every start of a command that reads conditions, as NamedTuples: a frozen
# dataclass costs far more to create (benchmarks/README.md, start-up, ninth pass).
NO_DATACLASSES = frozenset({"bagkit.selection.condition_terms"})


@pytest.mark.parametrize("case", ["find", "check"])
def test_a_quick_command_makes_no_dataclass_of_its_records(case: str) -> None:
    args = CASES[case][0]
    probe = (
        "import dataclasses, sys\n"
        "from bagkit.cli import launch\n"
        "made = []\n"
        "process = dataclasses._process_class\n"
        "def counted(cls, *args, **kwargs):\n"
        "    made.append(cls.__module__)\n"
        "    return process(cls, *args, **kwargs)\n"
        "dataclasses._process_class = counted\n"
        f"sys.argv = ['bagkit', *{args!r}]\n"
        "try:\n"
        "    launch.run()\n"
        "finally:\n"
        "    print('made', *made, file=sys.stderr)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=False
    )
    made = done.stderr.rsplit("made", 1)[-1].split()
    assert done.returncode == 0, done.stderr[-2000:]
    assert "bagkit.bag.metadata" in made  # the probe sees the classes made
    assert not NO_DATACLASSES & set(made), f"bagkit {' '.join(args)} makes dataclasses in {made}"
