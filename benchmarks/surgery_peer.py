"""pymcap-cli as the peer of ``filter`` and ``recover`` (issue 36, item 5): whole processes.

pymcap-cli is installed by ``uv`` in a venv of its own under ``benchmarks/results/peers/``
(made once, reused). Each command runs as a process from the shell, as a user runs it, both
tools on the same 1M-Imu bag (``bench_surgery._write``), interleaved, best of ``RUNS`` wall
times; their CPU times (user + sys of the child) are printed beside. Both load their modules
from cached bytecode, as installed packages do (where ``PYTHONDONTWRITEBYTECODE`` is set, a
module changed since the tree was compiled would be compiled again at every run). Every
output is checked by a doctor-equivalent read before its time counts: ``bagkit doctor
--deep`` on both (chunk CRCs, indexes against records, every message decoded), pymcap-cli's
own ``doctor`` on bagkit's, and equal message counts.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from benchmarks.bench_startup import cached_bytecode_env

PEER = "pymcap-cli"
PEER_DIR = Path(__file__).resolve().parent / "results" / "peers" / PEER
RUNS = 3
TARGET = 1.5
WINDOW = ("200", "800")  # seconds from the start of a 1,000 s bag: 600k of 1M kept
BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def peer_command() -> str | None:
    """The path of the peer's executable, installed on first use; None if it cannot be."""
    exe = PEER_DIR / "bin" / PEER
    if exe.exists():
        return str(exe)
    uv = shutil.which("uv", path=str(Path(sys.executable).parent)) or shutil.which("uv")
    if uv is None:
        return None
    try:
        subprocess.run([uv, "venv", "-q", "-p", sys.executable, str(PEER_DIR)], check=True)
        subprocess.run(
            [uv, "pip", "install", "-q", "--python", str(PEER_DIR / "bin" / "python"), PEER],
            check=True,
        )
    except subprocess.CalledProcessError:
        shutil.rmtree(PEER_DIR, ignore_errors=True)
        return None
    return str(exe)


def _timed(command: list[str], ok_codes: tuple[int, ...]) -> tuple[float, float]:
    """Wall and CPU seconds of one run of ``command`` (its exit code must be in ``ok_codes``)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, check=False, env=cached_bytecode_env())
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode not in ok_codes:
        raise RuntimeError(f"{' '.join(command)}: exit {done.returncode}: {done.stderr[-500:]!r}")
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return wall, cpu


def _checked_count(output: Path, peer: str | None) -> int:
    """Messages in ``output``, after ``bagkit doctor --deep`` and, given ``peer``, the peer's
    ``doctor`` found it healthy."""
    doctor = subprocess.run(
        [BAGKIT, "doctor", "--deep", str(output)], capture_output=True, check=False
    )
    if doctor.returncode != 0:
        raise RuntimeError(f"bagkit doctor {output}: {doctor.stdout[-500:]!r}")
    if peer is not None:
        mcap = next(output.glob("*.mcap"))
        theirs = subprocess.run([peer, "doctor", str(mcap)], capture_output=True, check=False)
        if theirs.returncode != 0:
            raise RuntimeError(f"{PEER} doctor {mcap}: {theirs.stdout[-500:]!r}")
    info = subprocess.run(
        [BAGKIT, "info", str(output), "--format", "json"], capture_output=True, check=True
    )
    return int(json.loads(info.stdout)["message_count"])


def _race(  # noqa: PLR0917 (two command makers, side by side)
    label: str,
    tmp: Path,
    ours: Callable[[Path], list[str]],
    theirs: Callable[[Path], list[str]],
    peer: str,
    ok_codes: tuple[int, ...],
) -> bool:
    """Run both ``RUNS`` times interleaved; print times and the ratio; True when >= TARGET."""
    times: dict[str, list[tuple[float, float]]] = {"bagkit": [], PEER: []}
    outputs = {"bagkit": tmp / "ours", PEER: tmp / "theirs.mcap"}
    for _ in range(RUNS):
        for name, make in (("bagkit", ours), (PEER, theirs)):
            out = outputs[name]
            shutil.rmtree(out, ignore_errors=True)
            out.unlink(missing_ok=True)
            times[name].append(_timed(make(out), ok_codes))
    # The peer's doctor (pure Python: 2 - 3 min of CPU for 600k messages here) checks ours.
    counts = {
        name: _checked_count(out, peer if name == "bagkit" else None)
        for name, out in outputs.items()
    }
    if counts["bagkit"] != counts[PEER]:
        raise RuntimeError(f"{label}: bagkit wrote {counts['bagkit']}, {PEER} {counts[PEER]}")
    best = {name: min(runs) for name, runs in times.items()}
    ratio = best[PEER][0] / best["bagkit"][0]
    print(
        f"  {label} ({counts['bagkit']:,} messages, both outputs healthy): "
        f"bagkit {best['bagkit'][0]:.2f} s ({best['bagkit'][1]:.2f} s CPU), "
        f"{PEER} {best[PEER][0]:.2f} s ({best[PEER][1]:.2f} s CPU): {ratio:.2f}x "
        f"(CPU {best[PEER][1] / best['bagkit'][1]:.2f}x; target >= {TARGET}x): "
        + ("met" if ratio >= TARGET else "MISSED"),
        flush=True,
    )
    return ratio >= TARGET


def against_pymcap_cli(bag: Path, tmp: Path) -> bool:
    """``filter`` to a time window and ``recover`` of a cut copy, bagkit against pymcap-cli."""
    peer = peer_command()
    if peer is None:
        print(f"  {PEER} could not be installed (uv, the package index): MISSED, not measured")
        return False
    mcap = next(bag.glob("*.mcap"))
    start, end = WINDOW
    met = _race(
        f"filter to a window, --start {start} --end {end}",
        tmp,
        lambda out: [BAGKIT, "filter", str(bag), "-o", str(out), "--start", start, "--end", end],
        lambda out: [
            peer,
            "filter",
            str(mcap),
            "-o",
            str(out),
            "-S",
            f"+{start}s",
            "-E",
            f"+{end}s",
        ],
        peer,
        (0,),
    )
    cut = tmp / "cut.mcap"
    with open(mcap, "rb") as src, open(cut, "wb") as dst:
        dst.write(src.read(os.path.getsize(mcap) * 3 // 4))
    # Both exit 3: output written, the input was truncated.
    met &= _race(
        "recover of the bag cut at 3/4",
        tmp,
        lambda out: [BAGKIT, "recover", str(cut), "-o", str(out)],
        lambda out: [peer, "recover", str(cut), "-o", str(out)],
        peer,
        (0, 3),
    )
    return met
