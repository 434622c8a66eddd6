"""PlayControls, the keyboard's key table and the CLI's ros2-bag-play argument forms (no DDS)."""

from __future__ import annotations

import threading
import time

import pytest
from typer.testing import CliRunner

from bagkit.bag.latched import LatchedOptions
from bagkit.cli.main import app
from bagkit.cli.replay_report import print_report
from bagkit.playback.controls import RATE_STEP, PlayControls
from bagkit.playback.errors import PlayerError
from bagkit.playback.keyboard import DOWN, RIGHT, SPACE, UP, key_actions, split_keys
from bagkit.playback.options import PlayOptions
from bagkit.playback.report import PlayReport
from bagkit.playback.source import MessageOrder
from bagkit.playback.timing import LatenessSummary, Timeline, effective_rate
from bagkit.selection.times import NS_PER_S

MS = 1_000_000


def test_pause_then_resume_continues_from_the_bag_time_reached() -> None:
    controls = PlayControls(2.0)
    controls.start(bag_start_ns=1000 * MS, wall_ns=0)
    assert controls.timeline.deadline(1100 * MS) == 50 * MS
    assert controls.pause(now_ns=30 * MS)  # bag time reached: 1000 + 30 * 2 = 1060 ms
    assert controls.holding and not controls.pause(now_ns=31 * MS)
    assert controls.resume(now_ns=5030 * MS)  # 5 s later
    # The message due 20 ms of wall time after the pause is due 20 ms after the resume.
    assert controls.timeline.deadline(1100 * MS) == 5050 * MS
    assert not controls.resume(now_ns=5031 * MS)


def test_a_rate_change_re_anchors_at_the_current_bag_time() -> None:
    controls = PlayControls(1.0)
    controls.start(bag_start_ns=0, wall_ns=0)
    assert controls.set_rate(4.0, now_ns=100 * MS)  # bag time 100 ms at wall 100 ms
    assert controls.timeline.deadline(500 * MS) == 200 * MS  # 400 ms of bag at 4x
    assert not controls.set_rate(0.0) and not controls.set_rate(-1.0)
    assert controls.rate == 4.0


def test_a_rate_change_while_paused_applies_on_resume() -> None:
    controls = PlayControls(1.0, paused=True)
    controls.start(bag_start_ns=0, wall_ns=0)
    controls.set_rate(2.0, now_ns=10 * MS)
    controls.resume(now_ns=100 * MS)
    assert controls.timeline.deadline(50 * MS) == 125 * MS


def test_changed_rate_is_reported_once_and_arrows_step_by_a_tenth() -> None:
    controls = PlayControls(1.0)
    seen: list[float] = []
    controls.on_rate_change = seen.append
    actions = key_actions(controls)
    actions[UP]()
    actions[UP]()
    actions[DOWN]()
    assert controls.rate == pytest.approx(1.0 + RATE_STEP)
    assert seen == pytest.approx([1.1, 1.2, 1.1])
    controls.set_rate(controls.rate)
    assert len(seen) == 3  # no change, no report
    slow = PlayControls(0.1)
    assert not key_actions(slow)[DOWN]()  # the rate never reaches 0
    assert slow.rate == 0.1


def test_space_toggles_and_a_step_is_taken_once_by_the_loop() -> None:
    controls = PlayControls(1.0)
    controls.start(bag_start_ns=0, wall_ns=0)
    actions = key_actions(controls)
    assert not controls.play_next(timeout_s=0.01)  # only while paused
    actions[SPACE]()
    assert controls.paused
    assert not controls.take_step(10 * MS)  # nothing requested
    results: list[bool] = []
    stepper = threading.Thread(target=lambda: results.append(bool(actions[RIGHT]())))
    stepper.start()
    generation = controls.generation
    while not controls.take_step(70 * MS):
        controls.wait_for_change(generation, 1.0)
        generation = controls.generation
    stepper.join(2.0)
    assert results == [True]
    assert not controls.take_step(80 * MS)
    controls.resume(now_ns=1000 * MS)  # continues after the stepped message
    assert controls.timeline.deadline(90 * MS) == 1020 * MS


def test_a_step_nobody_takes_times_out_and_is_forgotten() -> None:
    controls = PlayControls(1.0, paused=True)
    assert not controls.play_next(timeout_s=0.05)
    assert not controls.take_step(0)


def test_suspension_holds_without_touching_the_users_pause() -> None:
    controls = PlayControls(1.0)
    controls.start(bag_start_ns=0, wall_ns=0)
    controls.suspend(now_ns=100 * MS)
    assert controls.holding and not controls.paused
    controls.unsuspend(now_ns=3100 * MS)  # stopped 3 s: no message is overdue
    assert not controls.holding
    assert controls.timeline.deadline(150 * MS) == 3150 * MS
    controls.pause(now_ns=3200 * MS)
    controls.suspend(now_ns=3300 * MS)
    controls.unsuspend(now_ns=9000 * MS)
    assert controls.paused  # still paused by the user


def test_time_held_counts_pauses_and_suspensions_once_each() -> None:
    controls = PlayControls(1.0)
    controls.start(bag_start_ns=0, wall_ns=0)
    assert controls.held_ns(now_ns=500 * MS) == 0
    controls.pause(now_ns=1000 * MS)
    assert controls.held_ns(now_ns=1500 * MS) == 500 * MS  # paused now: counted up to now
    controls.toggle_paused(now_ns=3000 * MS)  # 2 s paused
    controls.suspend(now_ns=4000 * MS)
    controls.unsuspend(now_ns=5000 * MS)  # 1 s stopped
    controls.pause(now_ns=6000 * MS)
    controls.suspend(now_ns=6500 * MS)  # stopped while paused: held once, not twice
    controls.resume(now_ns=7000 * MS)  # resumed while stopped: still held
    controls.unsuspend(now_ns=8000 * MS)  # 2 s from the pause
    controls.resume(now_ns=9000 * MS)  # not paused: nothing changes
    assert controls.held_ns(now_ns=10_000 * MS) == 5000 * MS


def test_a_replay_started_paused_is_held_from_the_start() -> None:
    before = time.monotonic_ns()
    controls = PlayControls(1.0, paused=True)
    after = time.monotonic_ns()
    controls.resume(now_ns=after + 4000 * MS)
    # Held from when the controls were made, somewhere between before and after.
    assert 4000 * MS <= controls.held_ns() <= after - before + 4000 * MS


@pytest.mark.parametrize(
    ("paused_s", "line"),
    [
        (0.0, "150 messages in 4.957 s (9.903 s of bag time, rate 2)"),
        (12.5, "150 messages in 4.957 s played, 12.500 s paused (9.903 s of bag time, rate 2)"),
    ],
)
def test_the_closing_report_says_time_played_apart_from_time_paused(
    paused_s: float, line: str, capsys: pytest.CaptureFixture[str]
) -> None:
    report = PlayReport(
        topics=[],
        messages=150,
        loops=1,
        bag_duration_s=9.903,
        wall_duration_s=4.957 + paused_s,
        rate=2.0,
        lateness=LatenessSummary(0.0, 0.0, 0.0, 0),
        paused_s=paused_s,
    )
    assert report.to_dict()["played_s"] == pytest.approx(4.957)
    print_report(report)
    assert line in capsys.readouterr().out.splitlines()


def test_before_the_first_pass_the_position_is_where_the_pass_will_start() -> None:
    # A seek key pressed while the player waits for subscribers steps from there (it stepped
    # from bag time 0 and was clamped back to the window's start).
    controls = PlayControls(1.0)
    controls.cue(7000 * MS)
    assert controls.position(now_ns=3000 * MS) == 7000 * MS
    controls.seek(controls.position() + NS_PER_S)
    controls.start(bag_start_ns=7000 * MS, wall_ns=0)
    assert controls.take_seek() == 8000 * MS
    assert controls.position(now_ns=500 * MS) == 7500 * MS  # the timeline runs from the start


def test_keys_split_escape_sequences() -> None:
    assert split_keys(b" \x1b[C\x1b[Ax\x1b[B") == [SPACE, RIGHT, UP, b"x", DOWN]


def _options(args: list[str], monkeypatch: pytest.MonkeyPatch, command: str = "play") -> dict:
    seen: dict[str, object] = {}

    class FakePlayer:
        def __init__(self, options: PlayOptions, **_callbacks: object) -> None:
            seen.update(vars(options), bag=str(options.bag))
            raise PlayerError("stop here")

    monkeypatch.setattr("bagkit.ros.replay.player.Player", FakePlayer)
    result = CliRunner().invoke(app, [command, *args])
    assert result.exit_code == 2, result.output
    return seen


@pytest.mark.parametrize(
    "args",
    [
        ["BAG", "--clock", "--topics", "/a", "/b", "/c"],  # README's example
        ["--topics", "/a", "/b", "/c", "BAG"],
        ["BAG", "--topics", "/a,/b", "--topics", "/c"],
        ["BAG", "--topics", "/a", "/b", "-r", "1", "--topics=/c"],
        ["--clock", "100", "--topics", "/a,/b,/c", "BAG"],  # the clock's rate is not the bag
    ],
)
def test_topics_take_several_values_comma_lists_and_repeats(
    args: list[str], monkeypatch: pytest.MonkeyPatch, tmp_path: object
) -> None:
    monkeypatch.chdir(tmp_path)  # type: ignore[arg-type]
    (tmp_path / "BAG").mkdir()  # type: ignore[operator]
    seen = _options(args, monkeypatch)
    assert seen["topics"] == ("/a", "/b", "/c")
    assert seen["bag"] == "BAG"


def test_ros2_bag_play_options_reach_the_player(monkeypatch: pytest.MonkeyPatch) -> None:
    seen = _options(
        [
            "BAG",
            "-x",
            "^/tf",
            "--exclude-topics",
            "/a",
            "/b",
            "-p",
            "-l",
            "-d",
            "2",
            "--playback-duration",
            "3",
            "--playback-until-nsec",
            "17",
            "--remap",
            "/a:=/x",
            "/b:=/y",
            "--wait-for-all-acked",
            "0",
            "--qos-profile-overrides-path",
            "q.yaml",
            "-s",
            "mcap",
            "--read-ahead-queue-size",
            "10",
            "--disable-keyboard-controls",
        ],
        monkeypatch,
    )
    assert seen["exclude_regex"] == "^/tf"
    assert seen["exclude_topics"] == ("/a", "/b")
    assert seen["start_paused"] is True
    assert seen["loops"] == 0
    assert seen["delay_ns"] == 2 * NS_PER_S
    assert seen["duration_ns"] == 3 * NS_PER_S
    assert seen["until_ns"] == 17
    assert seen["remap"] == {"/a": "/x", "/b": "/y"}
    assert seen["waits"].ack_timeout_ns > 3600 * NS_PER_S  # type: ignore[attr-defined]
    assert str(seen["qos_overrides"]) == "q.yaml"


def test_old_spellings_still_work(monkeypatch: pytest.MonkeyPatch) -> None:
    seen = _options(
        ["BAG", "--exclude", "^/tf", "--duration", "3", "--qos-overrides", "q.yaml"],
        monkeypatch,
        command="replay",
    )
    assert (seen["exclude_regex"], seen["duration_ns"]) == ("^/tf", 3 * NS_PER_S)
    assert str(seen["qos_overrides"]) == "q.yaml"
    assert _options(["BAG", "--playback-until-sec", "1.5"], monkeypatch)["until_ns"] == (
        1_500_000_000
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--playback-until-sec", "1", "--playback-until-nsec", "1"], "exclude each other"),
        (["-s", "rosbag_v1"], "mcap and sqlite3"),
    ],
)
def test_conflicting_or_unknown_options_are_one_line(args: list[str], message: str) -> None:
    result = CliRunner().invoke(app, ["play", "BAG", *args])
    assert result.exit_code == 2
    assert message in result.output


@pytest.mark.parametrize("command", ["play", "replay"])
def test_help_answers_h(command: str) -> None:
    result = CliRunner().invoke(app, [command, "-h"])
    assert result.exit_code == 0
    assert "--start-paused" in result.output and "--exclude-regex" in result.output


def test_debug_options_reach_the_player(monkeypatch: pytest.MonkeyPatch) -> None:
    seen = _options(
        [
            *("A", "B", "-i", "C", "--message-order", "sent"),
            *("--latched-topics", "/x", "/y", "--seek-step", "2"),
        ],
        monkeypatch,
    )
    assert seen["bag"] == "A"
    assert [str(path) for path in seen["more_bags"]] == ["B", "C"]  # type: ignore[attr-defined]
    assert seen["message_order"] is MessageOrder.SENT
    assert seen["latched"] == LatchedOptions(enabled=True, extra_topics=("/x", "/y"))
    assert seen["seek_step_ns"] == 2_000_000_000
    assert _options(["-i", "A", "--no-latched"], monkeypatch)["latched"] == LatchedOptions(False)


def test_seek_keys_call_the_seek_step_both_ways() -> None:
    steps: list[int] = []
    actions = key_actions(PlayControls(), steps.append)
    for key in (b"\x1b[D", b",", b"<", b".", b">"):
        actions[key]()
    assert steps == [-1, -1, -1, 1, 1]
    assert b"." not in key_actions(PlayControls())  # no seek without a player to seek


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--topics", "/a"], "give a bag"),
        (["A", "--no-latched", "--latched-topics", "/x"], "exclude each other"),
        (["A", "--seek-step", "0"], "error: --seek-step: must be positive"),
    ],
)
def test_debug_option_errors_are_one_line(args: list[str], message: str) -> None:
    result = CliRunner().invoke(app, ["play", *args])
    assert result.exit_code == 2
    assert message in result.output


def test_the_effective_rate_after_a_resume_is_the_rate_in_force() -> None:
    """Paused 5 s after 1 s at rate 2: the progress shows 2x again, not 2 s of bag over 6 s."""
    controls = PlayControls(2.0)
    controls.start(bag_start_ns=0, wall_ns=0)
    pass_start = Timeline(0, 0, controls.rate)
    assert effective_rate(2000 * MS, 1000 * MS, controls.timeline, since=pass_start) == 2.0
    controls.pause(now_ns=1000 * MS)
    controls.resume(now_ns=6000 * MS)
    # The last message published before the pause is the position until the next one.
    assert effective_rate(2000 * MS, 6000 * MS, controls.timeline, since=pass_start) == 0.0
    assert effective_rate(3000 * MS, 6500 * MS, controls.timeline, since=pass_start) == 2.0
    controls.set_rate(4.0, now_ns=6500 * MS)
    assert effective_rate(5000 * MS, 7000 * MS, controls.timeline, since=pass_start) == 4.0
    # A seek starts a new segment: bag time before it does not count.
    seek = Timeline(10_000 * MS, 7000 * MS, controls.rate)
    assert effective_rate(12_000 * MS, 7500 * MS, controls.timeline, since=seek) == 4.0
