"""Topics whose messages do not decode, through ``export``, ``plot`` and ``find`` (in this
process, tests/bagkit_runs.py; one export a real process), as ``stats summary`` and ``echo``:
a topic none of whose messages decode ends the command with one error line and exit 2, the
others are done; a topic some of whose messages decode is done with a warning that counts the
rest."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess

from bagkit.bag import BagWriter, TopicInfo
from bagkit.data.export import export
from bagkit.data.series import read_series
from bagkit.fleet.find import find_fleet

T0 = 1_750_000_000_000_000_000
READING = "float64 value\nuint32 n\n"
CDR = b"\x00\x01\x00\x00"  # little-endian plain CDR encapsulation
GOOD = [CDR + np.float64(v).tobytes() + np.uint32(n).tobytes() for v, n in ((1.5, 3), (4.0, 0))]
SHORT = CDR + np.float64(2.5).tobytes()  # the uint32 is missing: does not decode
# /broken: nothing decodes; /mixed: good and short payloads alternate; /ok: a plain float64.
LAYOUT = {
    "/broken": [SHORT] * 5,
    "/mixed": [GOOD[i % 2] if i % 3 else SHORT for i in range(9)],
}


def _write_bag(path: Path, layout: dict[str, list[bytes]]) -> Path:
    with BagWriter(path) as bag:
        for topic in layout:
            bag.add_topic(TopicInfo(topic, "my_msgs/msg/Reading"), definition=READING)
        bag.add_topic(TopicInfo("/ok", "my_msgs/msg/Value"), definition="float64 value\n")
        for topic, payloads in layout.items():
            for i, payload in enumerate(payloads):
                bag.write(topic, payload, log_time=T0 + i * 1_000_000)
        for i in range(4):
            bag.write("/ok", CDR + np.float64(i).tobytes(), log_time=T0 + i * 1_000_000)
    return path


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write_bag(tmp_path_factory.mktemp("undecodable") / "bag", LAYOUT)


def _short(topic: str) -> int:
    return sum(payload == SHORT for payload in LAYOUT[topic])


def _run(*args: str | Path, process: bool = False) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py), or a real one."""
    done = bagkit_subprocess(list(args), Path.cwd()) if process else bagkit_in_process(list(args))
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr, done.stderr
    return done


def _lines(done: subprocess.CompletedProcess[str], kind: str) -> list[str]:
    return [line for line in done.stderr.splitlines() if line.startswith(kind)]


def _failed_on_broken(done: subprocess.CompletedProcess[str], bags: int = 1) -> None:
    assert done.returncode == 2, done.stderr
    assert _lines(done, "error:") == [
        f"error: none of the {bags * len(LAYOUT['/broken'])} messages of /broken decode"
    ]
    assert done.stderr.strip().splitlines()[-1].startswith("error:")


def test_the_library_counts_per_topic(bag: Path, tmp_path: Path) -> None:
    report = export(bag, tmp_path / "out")
    assert report.messages == {"/broken": 5, "/mixed": 9, "/ok": 4}
    assert report.undecodable == {"/broken": 5, "/mixed": _short("/mixed"), "/ok": 0}
    reading = read_series([bag], ["/mixed:n", "/broken:value"])
    assert reading.undecodable == {("bag", "/mixed"): _short("/mixed"), ("bag", "/broken"): 5}
    assert reading.none_decoded() == {"/broken": 5}
    assert [s.topic for s in reading.series] == ["/mixed"]
    found = find_fleet([bag], when="/mixed: n >= 0")
    assert (found.messages, found.undecodable, found.none_decoded) == (9, _short("/mixed"), False)


def test_export_writes_the_other_topics_then_fails(bag: Path, tmp_path: Path) -> None:
    done = _run("export", bag, "-o", tmp_path / "out", process=True)
    _failed_on_broken(done)
    warnings = _lines(done, "warning:")
    assert any(f"/mixed: {_short('/mixed')} messages could not be decoded" in w for w in warnings)
    mixed = pd.read_parquet(tmp_path / "out" / "mixed.parquet")
    decoded = [p for p in LAYOUT["/mixed"] if p != SHORT]
    assert mixed["n"].tolist() == [int(np.frombuffer(p[12:], np.uint32)[0]) for p in decoded]
    assert pd.read_parquet(tmp_path / "out" / "ok.parquet")["value"].tolist() == [0, 1, 2, 3]
    assert len(pd.read_parquet(tmp_path / "out" / "broken.parquet")) == 0

    partial = _run("export", bag, "-t", "/mixed", "-t", "/ok", "-o", tmp_path / "partial")
    assert partial.returncode == 0, partial.stderr
    assert len(_lines(partial, "warning:")) == 1 and not _lines(partial, "error:")


def test_export_pools_the_bags(bag: Path, tmp_path: Path) -> None:
    """Over two bags a topic that decodes in one is a warning, not an error."""
    fine = _write_bag(tmp_path / "fine", {"/broken": GOOD, "/mixed": GOOD})
    done = _run("export", bag, fine, "-t", "/broken", "-o", tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert len(_lines(done, "warning:")) == 1 and not _lines(done, "error:")
    other = _write_bag(tmp_path / "other", LAYOUT)
    both = _run("export", bag, other, "-t", "/broken", "-o", tmp_path / "both")
    _failed_on_broken(both, bags=2)


def test_plot_draws_the_other_series_then_fails(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "p.png"
    done = _run("plot", bag, "/broken:n", "/ok:value", "-o", out)
    _failed_on_broken(done)
    assert out.stat().st_size > 0 and "1 series ->" in done.stdout

    alone = _run("plot", bag, "/broken:value", "-o", tmp_path / "alone.png")
    _failed_on_broken(alone)
    assert not (tmp_path / "alone.png").exists()

    partial = _run("plot", bag, "/mixed:n", "-o", tmp_path / "mixed.html")
    assert partial.returncode == 0, partial.stderr
    (warning,) = _lines(partial, "warning:")
    assert f"/mixed: {_short('/mixed')} messages could not be decoded" in warning


@pytest.mark.parametrize("condition", ["n >= 0", "n >= 0 for 1ns"], ids=["bulk", "temporal"])
def test_find_says_the_topic_did_not_decode(bag: Path, condition: str) -> None:
    done = _run("find", bag, "--when", f"/broken: {condition}", "--format", "json")
    _failed_on_broken(done)
    assert json.loads(done.stdout) == []

    partial = _run("find", bag, "--when", f"/mixed: {condition}", "--format", "json")
    assert partial.returncode == 0, partial.stderr
    assert any(f"/mixed: {_short('/mixed')} messages" in w for w in _lines(partial, "warning:"))
    decoded = sum(p != SHORT for p in LAYOUT["/mixed"])
    assert sum(e["count"] for e in json.loads(partial.stdout)) == decoded
