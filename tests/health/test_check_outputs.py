"""``bagkit check``: --suggest from one flight kept by another, JUnit XML, the commands and
Foxglove links printed for a failure, an unreadable bag among the others, the library API."""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from urllib.parse import parse_qs, urlparse

import pytest
import yaml
from bagkit_runs import bagkit_in_process

import bagkit
from tests.health.flights import record_flight

FIXTURES = Path(__file__).parents[2] / "fixtures"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
NOMINAL = {  # fixtures/nominal/scenario.yaml's flight, seeds given per test
    "faults": "",
    "flight.takeoff_delay": 2.0,
    "flight.climb_duration": 15.0,
    "flight.cruise_duration": 10.0,
    "flight.descent_duration": 10.0,
    "flight.ground_duration": 3.0,
}
SPEC = """\
topics:
  /gps/fix:
    max_gap: 1500ms
    never: [isnan(*)]
  /temperature:
    values:
      temperature: {max: 50}
"""


def bagkit_cli(
    *args: str | Path, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py); ``play``, which starts DDS, and
    the filter command as printed, as real processes."""
    if args[0] != "play":
        return bagkit_in_process(list(args), env=dict(env or {}))
    return subprocess.run(
        [BAGKIT, *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
        env=None if env is None else {**os.environ, **env},
    )


@pytest.fixture(scope="module")
def flights(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Two nominal flights of the whole system, other seeds (other noise, other biases)."""
    where = tmp_path_factory.mktemp("flights")
    return tuple(  # type: ignore[return-value]
        where / f"seed{seed}"
        for seed in (3, 11)
        if record_flight(where / f"seed{seed}", 48.0, {**NOMINAL, "seed": seed})
    )


def test_a_nominal_flight_keeps_the_contract_suggested_from_another(
    flights: tuple[Path, Path], tmp_path: Path
) -> None:
    first, second = flights
    suggested = bagkit_cli("check", first, "--suggest")
    assert suggested.returncode == 0, suggested.stderr
    spec = yaml.safe_load(suggested.stdout)
    as_json = bagkit_cli("check", first, "--suggest", "--format", "json")
    assert json.loads(as_json.stdout) == spec  # the same contract, for scripts
    imu = spec["topics"]["/imu/data"]
    # What the flight shows, read back independently: 10 Hz, so a 1 s window, and no NaN.
    assert imu["type"] == "sensor_msgs/msg/Imu" and imu["never"] == ["isnan(*)"]
    assert imu["rate"]["over"] == "1s" and 0 < imu["rate"]["min"] < 10
    assert 100 < int(imu["max_gap"].removesuffix("ms")) < 1000
    assert "header.stamp.sec" not in imu["values"]  # stamps grow from run to run
    low, high = (
        imu["values"]["linear_acceleration.z"]["min"],
        imu["values"]["linear_acceleration.z"]["max"],
    )
    assert low < 9.81 < high
    path = tmp_path / "health.yaml"
    path.write_text(suggested.stdout)
    kept = bagkit_cli("check", first, second, FIXTURES / "nominal" / "golden", "--spec", path)
    assert kept.returncode == 0, kept.stdout + kept.stderr
    # The faults fixture breaks it where its faults are: the GPS's NaN among them.
    broken = broken_in("faults", path)
    assert ("/gps/fix", "isnan(*)") in broken


def broken_in(fixture: str, spec: Path) -> list[tuple[str, str]]:
    result = bagkit.check(FIXTURES / fixture / "golden", spec)
    return [(a.topic, a.what) for report in result.reports for a in report.broken]


def test_junit_json_commands_and_links_of_a_failure(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    junit = tmp_path / "out" / "check.xml"
    bag = FIXTURES / "faults" / "golden"
    result = bagkit_cli(
        "check",
        bag,
        "--spec",
        spec,
        "--format",
        "json",
        "--junit",
        junit,
        env={"BAGKIT_BAGS_URL": "https://bags.example.com/store"},
    )
    assert result.returncode == 1, result.stderr
    (report,) = json.loads(result.stdout)
    failed = [a for a in report["assertions"] if not a["passed"]]
    assert [(a["topic"], a["assertion"]) for a in failed] == [
        ("/gps/fix", "isnan(*)"),
        ("/temperature", "temperature > 50"),
    ]
    suites = ET.parse(junit).getroot()
    (suite,) = suites.findall("testsuite")
    cases = suite.findall("testcase")
    assert int(suite.get("tests")) == len(cases) == len(report["assertions"])
    assert int(suite.get("failures")) == 2
    failures = {c.get("name"): c.find("failure") for c in cases if c.find("failure") is not None}
    assert set(failures) == {"/gps/fix: isnan(*)", "/temperature: temperature > 50"}
    assert "bagkit filter" in (failures["/gps/fix: isnan(*)"].text or "")
    # The Foxglove link opens the bag's MCAP file where bags are served, at the episode.
    gps = failed[0]
    query = parse_qs(urlparse(gps["foxglove"]).query)
    assert query["ds"] == ["remote-file"]
    (mcap,) = bag.glob("*.mcap")
    assert query["ds.url"] == [f"https://bags.example.com/store/{mcap.as_posix().lstrip('/')}"]
    start_ns = gps["episodes"][0]["start_ns"]
    assert query["time"][0].endswith(f".{start_ns % 10**9:09d}Z")
    # The filter command, run as printed, cuts one bag around each episode.
    play, cut = gps["commands"]
    done = subprocess.run(
        [BAGKIT, *shlex.split(cut)[1:]],
        check=False,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    cuts = list((tmp_path / "golden_cuts").iterdir())
    assert len(cuts) == len(gps["episodes"])
    assert play.split()[:3] == ["bagkit", "play", str(bag)]
    offset = float(play.split("--start-offset ")[1])
    assert offset == pytest.approx(max(gps["episodes"][0]["start_s"] - 5, 0), abs=1e-3)


@pytest.mark.ros
def test_the_play_command_is_accepted_as_printed(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    result = bagkit.check(FIXTURES / "faults" / "golden", spec)
    (report,) = result.reports
    play = report.broken[0].commands(report.bag, report.start_ns)[0]
    done = bagkit_cli(
        *shlex.split(play)[1:],
        "--playback-duration",
        "0.2",
        env={"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"},
    )
    assert done.returncode == 0, done.stderr


def test_an_unreadable_bag_is_reported_among_the_others(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"not a bag" * 10)
    junit = tmp_path / "check.xml"
    result = bagkit_cli(
        "check", FIXTURES / "nominal" / "golden", broken, "--spec", spec, "--junit", junit
    )
    assert result.returncode == 2, result.stdout + result.stderr
    suites = ET.parse(junit).getroot().findall("testsuite")
    assert [int(s.get("errors") or 0) for s in suites] == [0, 1]
    assert [int(s.get("failures") or 0) for s in suites] == [0, 0]
    assert "fixtures/nominal/golden: 5 assertions, healthy" in result.stdout
    assert f"{broken}: not read" in result.stdout
    assert "Traceback" not in result.stderr


def test_the_library_is_the_top_level() -> None:
    spec = bagkit.HealthSpec.parse(SPEC)
    result = bagkit.check([FIXTURES / "nominal" / "golden", FIXTURES / "faults" / "golden"], spec)
    assert isinstance(result, bagkit.CheckResult)
    assert [r.passed for r in result.reports] == [True, False] and result.exit_code == 1
    assert bagkit.parse_condition("gap > 1s").temporal


def test_bad_names_are_named_with_their_line_or_a_guess(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(
        "topics:\n  /imu/data:\n    max_gap: 1s\n    values:\n      linear_accel.z: {max: 5}\n"
    )
    result = bagkit_cli("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    (line,) = result.stderr.splitlines()
    assert result.returncode == 2 and line.startswith(f"error: {spec}:5: /imu/data: ")
    assert "did you mean linear_acceleration.z" in line
    spec.write_text("topics:\n  /imu/dat: {}\n")
    result = bagkit_cli("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert result.returncode == 1
    assert "present (not in the bag; did you mean /imu/data?)" in result.stdout


def test_the_table_fits_80_columns_but_for_commands_and_links(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    result = bagkit_cli(
        "check", FIXTURES / "faults" / "golden", "--spec", spec, "--bags-url", "https://b.example/"
    )
    assert result.returncode == 1
    lines = result.stdout.splitlines()
    whole = [ln for ln in lines if ln.strip().startswith(("bagkit ", "https://"))]
    assert len(whole) == 2 * 3  # play, filter and a Foxglove link per failure
    assert all(len(ln) <= 80 for ln in lines if ln not in whole), lines


def test_the_foxglove_link_of_a_split_bag_opens_the_file_holding_the_break(tmp_path: Path) -> None:
    """A bag split every 5 s: each failure's link names the file whose messages span its
    first break, not the bag's first file (where Foxglove would find no such time)."""
    from mcap.reader import make_reader

    split = tmp_path / "split"
    done = bagkit_cli("filter", FIXTURES / "faults" / "golden", "-o", split, "-d", "5")
    assert done.returncode == 0, done.stderr
    starts = {}
    for file in split.glob("*.mcap"):
        with open(file, "rb") as f:
            statistics = make_reader(f).get_summary().statistics  # type: ignore[union-attr]
        starts[file.name] = statistics.message_start_time
    assert len(starts) > 3
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    result = bagkit_cli(
        "check", split, "--spec", spec, "--format", "json", "--bags-url", "https://b/"
    )
    (report,) = json.loads(result.stdout)
    failed = [a for a in report["assertions"] if not a["passed"]]
    assert failed
    for assertion in failed:
        start = assertion["episodes"][0]["start_ns"]
        holding = max((t, name) for name, t in starts.items() if t <= start)[1]
        (url,) = parse_qs(urlparse(assertion["foxglove"]).query)["ds.url"]
        assert url == f"https://b/{(split / holding).as_posix().lstrip('/')}"


def test_the_foxglove_link_of_a_bag_in_storage_names_its_bucket_and_key() -> None:
    """``s3://fleet/day1/c2`` is found under the base URL as ``fleet/day1/c2/...``, not as
    ``s3%3A/fleet/...``; the file is the one holding the time."""
    from bagkit.health.links import foxglove_link

    files = [(10, "c2_0.mcap"), (20, "c2_1.mcap")]
    link = foxglove_link("https://bags.example.com/", "s3://fleet/day1/c2", 25, files)
    (url,) = parse_qs(urlparse(link).query)["ds.url"]
    assert url == "https://bags.example.com/fleet/day1/c2/c2_1.mcap"
    one = foxglove_link("https://b", "gs://fleet/a.mcap", 25, [(10, "a.mcap")])
    assert parse_qs(urlparse(one).query)["ds.url"] == ["https://b/fleet/a.mcap"]


def test_the_cut_command_of_a_bag_file_names_its_output_without_the_suffix(
    tmp_path: Path,
) -> None:
    """``bagkit check run.mcap``: the filter command printed writes ``run_cuts`` (not
    ``run.mcap_cuts``), and runs as printed."""
    (golden,) = (FIXTURES / "faults" / "golden").glob("*.mcap")
    bag = tmp_path / "run.mcap"
    bag.write_bytes(golden.read_bytes())
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    result = bagkit_in_process(
        ["check", "run.mcap", "--spec", spec, "--format", "json"], cwd=tmp_path
    )
    (report,) = json.loads(result.stdout)
    _, cut = next(a for a in report["assertions"] if not a["passed"])["commands"]
    assert " -o run_cuts " in cut
    done = subprocess.run(
        [BAGKIT, *shlex.split(cut)[1:]], capture_output=True, text=True, check=False, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert list((tmp_path / "run_cuts").iterdir())
