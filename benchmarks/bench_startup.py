"""Whole-process start of the quick commands against ``python -c pass``.

Target (issue 36, item 2): ``bagkit --help``, ``info``, ``echo -n 1``, ``stats summary``,
``find`` and ``check`` each within 0.1 s of ``python -c pass`` in the same environment. Every
command is run RUNS times, interleaved with the peers so that a change of machine load hits them
alike; the median wall time of each is compared (the best run is printed beside it).
``python -c "import numpy"`` is printed beside them, for scale: ``info`` imports no numpy (not
for a bag with services either: their events are read by their fixed header, the message index
ordered without it), ``echo`` decodes with it, and ``stats``, ``find`` and ``check`` decode in
bulk with it; ``import numpy, typer`` is the floor of a command that decodes behind bagkit's
command line, printed also as bagkit runs it, with numpy's OpenBLAS on one thread. ``info
BAG`` is a two-topic bag of our own; the others run on ``fixtures/fast`` (sensor topics and a
service), as ``tests/cli/test_startup_imports.py`` does; ``check`` with a contract of rate,
gap, value and presence assertions (``fixtures/fast/health.yaml``).

Run: ``.venv/bin/python -m benchmarks startup``
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bagkit.bag import BagWriter, TopicInfo

RUNS = 9
TARGET_S = 0.10
FAST_BAG = Path(__file__).resolve().parents[1] / "fixtures" / "fast" / "golden"
STRING = "std_msgs/msg/String"
CONTRACT = FAST_BAG.parent / "health.yaml"


def _small_bag(directory: Path) -> Path:
    """A bag of two topics, 200 messages: what a user opens with ``bagkit info``."""
    path = directory / "startup"
    payload = b"\x00\x01\x00\x00\x04\x00\x00\x00abc\x00"
    with BagWriter(path) as bag:
        for topic in ("/a", "/b"):
            bag.add_topic(TopicInfo(topic, STRING))
        for i in range(200):
            bag.write("/a" if i % 2 else "/b", payload, log_time=1_000_000_000 + i * 10_000_000)
    return path


# As on a user's machine: modules are loaded from their cached bytecode (an environment that
# sets PYTHONDONTWRITEBYTECODE would compile bagkit's modules from source at every start).
def cached_bytecode_env() -> dict[str, str]:
    """This process's environment without ``PYTHONDONTWRITEBYTECODE``."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


# bagkit's console script runs numpy's OpenBLAS on one thread (bagkit.cli.launch); this peer
# shows what numpy and typer cost a process that does the same.
ONE_BLAS_THREAD = "OPENBLAS_NUM_THREADS=1 "


def _wall(command: list[str]) -> float:
    env = cached_bytecode_env()
    if command[0] == ONE_BLAS_THREAD:
        command, env = command[1:], {**env, "OPENBLAS_NUM_THREADS": "1"}
    start = time.perf_counter()
    subprocess.run(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, env=env
    )
    return time.perf_counter() - start


def main() -> bool:
    """Print the median start times and their differences to ``python -c pass``."""
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    with tempfile.TemporaryDirectory() as tmp:
        bag = _small_bag(Path(tmp))
        commands = {
            "python -c pass": [sys.executable, "-c", "pass"],
            "python -c 'import numpy'": [sys.executable, "-c", "import numpy"],
            "python -c 'import numpy, typer'": [sys.executable, "-c", "import numpy, typer"],
            "the same, one BLAS thread": [
                ONE_BLAS_THREAD,
                sys.executable,
                "-c",
                "import numpy, typer",
            ],
            "bagkit --help": [bagkit, "--help"],
            "bagkit info BAG": [bagkit, "info", str(bag)],
            "bagkit info fast": [bagkit, "info", str(FAST_BAG)],
            "bagkit echo fast -n 1": [bagkit, "echo", str(FAST_BAG), "/imu/data", "-n", "1"],
            "bagkit stats summary fast": [bagkit, "stats", "summary", str(FAST_BAG)],
            "bagkit find fast": [
                *(bagkit, "find", str(FAST_BAG)),
                *("--when", "/imu/data: linear_acceleration.z < 5"),
            ],
            "bagkit check fast": [bagkit, "check", str(FAST_BAG), "--spec", str(CONTRACT)],
        }
        for command in commands.values():  # warm-up: bytecode caches, page cache
            _wall(command)
        times: dict[str, list[float]] = {name: [] for name in commands}
        for _ in range(RUNS):
            for name, command in commands.items():
                times[name].append(_wall(command))
    medians = {name: statistics.median(t) for name, t in times.items()}
    best = {name: min(t) for name, t in times.items()}
    ok = True
    print(
        f"median and best of {RUNS} runs each, interleaved; target: bagkit's median within "
        f"{TARGET_S} s of pass"
    )
    for name, median in medians.items():
        over = median - medians["python -c pass"]
        best_over = best[name] - best["python -c pass"]
        verdict = ""
        if name.startswith("bagkit"):
            met = over <= TARGET_S
            ok &= met
            verdict = "ok" if met else "MISSED"
        print(
            f"  {name:33s} median {median * 1000:7.1f} ms (+{over * 1000:6.1f} ms), "
            f"best {best[name] * 1000:7.1f} ms (+{best_over * 1000:6.1f} ms) {verdict}"
        )
    return ok


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
