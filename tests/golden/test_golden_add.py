"""``bagkit golden add``: a window of a recording becomes a fixture that pytest runs at once.

In a temporary copy of the repository (as the mutation proof): a window of the faults
fixture's golden is made a fixture ``--like fixtures/faults``; its lockstep test passes on the
unchanged code, and fails once the code under test is changed by 1%.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml
from bagkit_runs import bagkit_in_process
from test_mutation import EXPONENT, failing, mutated_copy, run_golden

from bagkit.bag import BagReader
from bagkit.regression.spec import load_spec
from bagkit.words import counted

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _bagkit(copy: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(copy))
    return subprocess.run(
        [BAGKIT, *args], cwd=copy, env=env, capture_output=True, text=True, timeout=300, check=False
    )


def test_a_window_made_a_fixture_passes_then_catches_a_mutation(tmp_path: Path) -> None:
    copy = mutated_copy(tmp_path, "fusion/estimation/isa.py", EXPONENT, EXPONENT)
    added = _bagkit(
        copy, "golden", "add", "fixtures/incident", "--from", "fixtures/faults/golden",
        "--start", "5", "--end", "15", "--like", "fixtures/faults",
    )  # fmt: skip
    assert added.returncode == 0, added.stderr
    fixture = copy / "fixtures" / "incident"
    assert sorted(p.name for p in fixture.iterdir()) == ["golden", "spec.yaml"]
    spec, faults = load_spec(fixture), load_spec(copy / "fixtures" / "faults")
    assert (spec.inputs, spec.outputs, spec.processor) == (
        faults.inputs,
        faults.outputs,
        faults.processor,
    )
    with BagReader(fixture / "golden") as window, BagReader(faults.bag) as whole:
        assert window.start_ns >= whole.start_ns + 5 * 10**9
        assert window.end_ns < whole.start_ns + 15 * 10**9
        for topic in spec.inputs:  # the inputs are the window's, as recorded
            inside = [
                m.log_time
                for m in whole.messages([topic])
                if whole.start_ns + 5 * 10**9 <= m.log_time < whole.start_ns + 15 * 10**9
            ]
            assert [m.log_time for m in window.messages([topic])] == inside
    # The spec fits the new fixture: no copied description, the window's duration, no
    # record_launch reading the old folder's scenario; the rest as the old spec has it.
    new = yaml.safe_load((fixture / "spec.yaml").read_text())
    old = yaml.safe_load((copy / "fixtures" / "faults" / "spec.yaml").read_text())
    assert "{fixture}" in str(old["record_launch"]) and "record_launch" not in new
    assert (new["description"], new["duration"]) == ("", 10)
    assert old["description"] and old["duration"] != 10
    for key in ("description", "duration", "record_launch"):
        old.pop(key), new.pop(key, None)
    assert new == old

    passed, _ = run_golden(copy, "incident")
    assert passed.returncode == 0, passed.stdout + passed.stderr

    isa = copy / "fusion" / "estimation" / "isa.py"
    isa.write_text(isa.read_text().replace(EXPONENT, f"_EXPONENT = {0.190263 * 1.01!r}"))
    failed, report = run_golden(copy, "incident")
    assert failed.returncode == 1, failed.stdout + failed.stderr
    assert "pose.pose.position.z" in failing(report)["/fusion/baro_altitude"]["failed_fields"]


def test_without_like_the_window_is_kept_and_the_spec_is_a_template(tmp_path: Path) -> None:
    copy = mutated_copy(tmp_path, "fusion/estimation/isa.py", EXPONENT, EXPONENT)
    added = _bagkit(
        copy, "golden", "add", "fixtures/raw", "--from", "fixtures/faults/golden", "--end", "3"
    )
    assert added.returncode == 0, added.stderr
    text = (copy / "fixtures" / "raw" / "spec.yaml").read_text()
    with BagReader(copy / "fixtures" / "raw" / "golden") as window:
        for topic, count in window.topic_counts.items():
            assert f"#   {topic}: {window.topics[topic].type}, {counted(count, 'message')}" in text
    again = _bagkit(copy, "golden", "add", "fixtures/raw", "--from", "fixtures/faults/golden")
    assert again.returncode != 0 and again.stderr.startswith("error: fixtures/raw exists")
    assert again.stderr.count("\n") == 1


def test_around_takes_the_first_episode_with_its_margins(tmp_path: Path) -> None:
    from bagkit.data.episodes import find_episodes
    from bagkit.regression.add import AddOptions, add_fixture
    from bagkit.regression.golden import check_lockstep
    from bagkit.selection.conditions import parse_topic_condition

    faults = load_spec(Path(__file__).resolve().parents[2] / "fixtures" / "faults")
    trigger = "/alerts: status[*].level >= 2"
    with BagReader(faults.bag) as reader:
        found = find_episodes(reader, parse_topic_condition(trigger))
    first = found.episodes[0]
    assert len(found.episodes) > 1
    options = AddOptions(
        faults.bag, like=faults.directory, around=trigger, before_ns=10**9, after_ns=3 * 10**9
    )
    added = add_fixture(tmp_path / "alert", options)
    assert added.episodes == len(found.episodes)
    with BagReader(tmp_path / "alert" / "golden") as window:
        inputs = [m.log_time for m in window.messages(faults.inputs)]
    assert first.start_ns - 10**9 <= min(inputs) and max(inputs) <= first.end_ns + 3 * 10**9
    assert check_lockstep(load_spec(tmp_path / "alert"), tmp_path / "work").passed


def test_episode_picks_another_episode_and_one_past_the_last_is_one_line(tmp_path: Path) -> None:
    from bagkit.data.episodes import find_episodes
    from bagkit.selection.conditions import parse_topic_condition

    faults = load_spec(Path(__file__).resolve().parents[2] / "fixtures" / "faults")
    trigger = "/alerts: status[*].level >= 2"
    with BagReader(faults.bag) as reader:
        found = find_episodes(reader, parse_topic_condition(trigger), 10**9)
    assert len(found.episodes) > 1
    last = found.episodes[-1]
    fixture = tmp_path / "last"
    common = ["--from", str(faults.bag), "--around", trigger, "--gap", "1", "--after", "1"]
    made = _bagkit(
        tmp_path, "golden", "add", str(fixture), *common, "--episode", str(len(found.episodes))
    )
    assert made.returncode == 0, made.stderr
    assert f"{len(found.episodes)} episodes" in made.stderr
    with BagReader(fixture / "golden") as window:
        times = [m.log_time for m in window.messages(["/alerts"])]
    # The window starts at the episode's first match (the latched copies are logged there too).
    assert min(times) == last.start_ns and max(times) <= last.end_ns + 10**9

    past = _bagkit(
        tmp_path,
        "golden",
        "add",
        str(tmp_path / "past"),
        *common,
        "--episode",
        str(len(found.episodes) + 1),
    )
    assert past.returncode == 2, past.stderr
    lines = past.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "there are" in lines[0]
    assert not (tmp_path / "past").exists()


def test_a_span_from_the_end_is_read_against_the_bag(tmp_path: Path) -> None:
    """The library takes the window as a query holds it: ``-5`` is five seconds before the
    bag's last message; the spec's first line names the window in absolute times."""
    from bagkit.regression.add import AddOptions, add_fixture
    from bagkit.selection.query import Query
    from bagkit.selection.times import format_ns

    faults = load_spec(Path(__file__).resolve().parents[2] / "fixtures" / "faults")
    with BagReader(faults.bag) as reader:
        last = reader.end_ns
        expected = [m.log_time for m in reader.messages() if m.log_time >= last - 5 * 10**9]
    added = add_fixture(tmp_path / "tail", AddOptions(faults.bag, Query.create(start="-5").span))
    with BagReader(tmp_path / "tail" / "golden") as window:
        # The latched state (logged at the start) aside, the messages are the bag's last 5 s.
        got = [m.log_time for m in window.messages() if m.log_time > last - 5 * 10**9]
    assert got == [t for t in expected if t > last - 5 * 10**9] and got
    assert sum(added.counts.values()) >= len(expected)
    first_line = (tmp_path / "tail" / "spec.yaml").read_text().splitlines()[0]
    assert f"[{format_ns(last - 5 * 10**9)}, end)" in first_line


def test_like_a_spec_without_a_processor_is_one_line_naming_the_flag(tmp_path: Path) -> None:
    """A spec that only launches nodes cannot make the window's expected outputs in lockstep:
    one error naming ``--like``, and nothing written."""
    root = Path(__file__).resolve().parents[2]
    launched = tmp_path / "launched"
    launched.mkdir()
    spec = (root / "fixtures" / "faults" / "spec.yaml").read_text()
    kept = [
        line
        for line in spec.splitlines()
        if not line.startswith(("processor", "  nodes:", "    data_logger", "    alert_system"))
        and not line.startswith("    sensor_fusion")
    ]
    (launched / "spec.yaml").write_text("\n".join(kept) + "\n")
    (launched / "golden").symlink_to(root / "fixtures" / "faults" / "golden")
    assert load_spec(launched).processor is None
    proc = bagkit_in_process(
        ["golden", "add", tmp_path / "new", "--from", launched / "golden", "--like", launched],
        tmp_path,
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.startswith("error: --like needs a spec with a processor: ")
    assert f"{launched / 'spec.yaml'} has no processor" in proc.stderr
    assert proc.stderr.count("\n") == 1
    assert not (tmp_path / "new").exists()
