"""run_app, the last line of defence: whatever escapes a command is one line and an exit code."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
import typer

from bagkit.cli import common, progress
from bagkit.cli.common import (
    EXIT_BROKEN_PIPE,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    handle_errors,
    run_app,
)
from bagkit.errors import BagkitError
from bagkit.words import counted

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
FIXTURE = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"


def _recurse(depth: int) -> int:
    return _recurse(depth + 1) + 1


def _raises(action: Callable[[], object]) -> typer.Typer:
    """An app whose one command (wrapped like bagkit's) runs ``action``."""
    app = typer.Typer(pretty_exceptions_enable=False)

    @app.command()
    @handle_errors
    def run() -> None:
        action()

    return app


def _exit(app: typer.Typer, capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    with pytest.raises(SystemExit) as info:
        run_app(app, [])
    code = info.value.code
    assert isinstance(code, int)
    return code, capsys.readouterr().err.splitlines()


def _bag_error() -> None:
    raise BagkitError("the bag is odd")


def _markup_error() -> None:
    raise BagkitError("topic [/]x[bold]\nsecond line")


def _huge_error() -> None:
    raise BagkitError("x" * 5000)


def _interrupt() -> None:
    raise KeyboardInterrupt


@pytest.mark.parametrize(
    ("action", "code", "line"),
    [
        (lambda: _recurse(0), EXIT_INTERNAL, "error: internal error: RecursionError: maximum"),
        (lambda: bytearray(1 << 62), EXIT_INTERNAL, "error: out of memory: MemoryError"),
        (lambda: (1, 2)[len("abc")], EXIT_INTERNAL, "error: internal error: IndexError: tuple"),
        (_interrupt, EXIT_INTERRUPTED, "error: interrupted"),
        (_bag_error, 2, "error: the bag is odd"),
        (_markup_error, 2, "error: topic [/]x[bold] second line"),
        (_huge_error, 2, f"error: {'x' * 1000}... (4,000 characters cut)"),
    ],
    ids=["recursion", "memory", "index", "ctrl-c", "bagkit-error", "markup-newline", "huge"],
)
def test_one_line_and_a_documented_exit_code(
    capsys: pytest.CaptureFixture[str], action: Callable[[], object], code: int, line: str
) -> None:
    exit_code, lines = _exit(_raises(action), capsys)
    assert exit_code == code
    assert len(lines) == 1 and lines[0].startswith(line), lines


def _swallowed_interrupt() -> None:
    """Ctrl-C while Python runs a gc callback or ``__del__``: the exception is printed, not
    raised."""
    try:
        os.kill(os.getpid(), signal.SIGINT)
        signal.pthread_sigmask(signal.SIG_BLOCK, [])  # a call: the handler runs before it returns
    except KeyboardInterrupt:
        pass


class _InterruptedFinalizer:
    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        signal.pthread_sigmask(signal.SIG_BLOCK, [])


def _interrupt_in_a_finalizer() -> None:
    """Ctrl-C inside ``__del__`` (as in Dask's gc callback): Python hands the exception to
    ``sys.unraisablehook``, which would print it with its traceback."""
    _InterruptedFinalizer()


_LOOPED_ON: list[bool] = []


def _a_loop_after_an_interrupted_finalizer() -> None:
    """A looping replay whose Ctrl-C landed in a finalizer: it must stop, not loop on."""
    _InterruptedFinalizer()
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        time.sleep(0.01)
    _LOOPED_ON.append(True)


@pytest.mark.parametrize(
    "action",
    [_swallowed_interrupt, _interrupt_in_a_finalizer, _a_loop_after_an_interrupted_finalizer],
)
def test_a_swallowed_ctrl_c_still_ends_with_exit_130(
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    action: Callable[[], None],
) -> None:
    unraisable: list[object] = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    # As from a shell: a test runner's worker may ignore SIGINT.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        exit_code, lines = _exit(_raises(action), capsys)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert (exit_code, lines) == (EXIT_INTERRUPTED, ["error: interrupted"])
    assert not _LOOPED_ON
    assert unraisable == []  # nothing printed the ignored KeyboardInterrupt
    assert signal.getsignal(signal.SIGINT) is previous
    assert sys.unraisablehook == unraisable.append


def test_an_internal_error_names_where_it_was_raised_and_asks_for_a_report(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The innermost frame inside the bagkit package: here handle_errors' call of the command."""
    monkeypatch.delenv("BAGKIT_TRACEBACK", raising=False)
    _, lines = _exit(_raises(lambda: int("x")), capsys)
    assert " at bagkit/cli/common.py:" in lines[0]
    assert lines[0].endswith("; please report it (BAGKIT_TRACEBACK=1 prints the traceback)")


def test_bagkit_traceback_prints_the_traceback_first(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BAGKIT_TRACEBACK", "1")
    _, lines = _exit(_raises(lambda: int("x")), capsys)
    assert lines[0] == "Traceback (most recent call last):"
    assert lines[-2] == "ValueError: invalid literal for int() with base 10: 'x'"
    assert lines[-1].startswith("error: internal error: ValueError")


@pytest.mark.parametrize(
    "command",
    [
        ["info", str(FIXTURE)],
        ["info", "--format", "json", str(FIXTURE)],
        ["info", "-t", str(FIXTURE)],
        ["stats", "summary", str(FIXTURE)],
        ["stats", "summary", "--format", "csv", str(FIXTURE)],
        ["echo", str(FIXTURE), "/imu/data", "-n", "5"],
        ["echo", str(FIXTURE), "/imu/data", "--format", "json"],
        ["compare", str(FIXTURE), str(FIXTURE)],
        ["doctor", str(FIXTURE)],
    ],
)
def test_a_closed_output_pipe_is_quiet_and_exit_141(command: list[str]) -> None:
    """The reader of stdout is gone before the first write (as `| head` does, sooner)."""
    proc = subprocess.Popen([BAGKIT, *command], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()
    stderr = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == EXIT_BROKEN_PIPE, stderr
    assert stderr == ""


def test_head_ends_a_long_output_quietly() -> None:
    """A real `| head`: the reader goes away after the first line of an output (about 250 KB of
    YAML) larger than the pipe's buffer."""
    pipeline = subprocess.run(
        f"'{BAGKIT}' echo '{FIXTURE}' /imu/data | head -1; echo \"status ${{PIPESTATUS[0]}}\"",
        shell=True,
        executable="/bin/bash",
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert pipeline.stderr == ""
    first, status = pipeline.stdout.splitlines()
    assert first.startswith("# /imu/data at ")
    assert status == f"status {EXIT_BROKEN_PIPE}"


def test_the_progress_bar_stays_off_a_stderr_that_is_no_terminal(
    capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A slow command's bar is for a terminal: a log gets nothing (a stopped bar left a blank
    line, which broke scripts that expect an empty stderr)."""
    monkeypatch.setattr(progress, "PROGRESS_DELAY_S", 0.0)
    bar = progress.DelayedProgress("reading")
    bar(1, 10)
    bar(10, 10)
    bar.close()
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("styled", [False, True], ids=["pipe", "FORCE_COLOR"])
def test_warning_and_error_lines_say_the_same_plain_or_styled(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], styled: bool
) -> None:
    # Into a pipe they are written without rich; with colours, through it: the same text.
    if styled:
        monkeypatch.setenv("FORCE_COLOR", "1")
    else:
        monkeypatch.delenv("FORCE_COLOR", raising=False)
    common.warn("topic [/]x[bold]\nsecond line")
    message = "bad [red]value[/] " + "y" * 2000
    exit_ = common.fail(message, 3)
    assert exit_.exit_code == 3
    err = re.sub(r"\x1b\[[0-9;]*m", "", capsys.readouterr().err)
    assert err.splitlines() == [
        "warning: topic [/]x[bold] second line",
        f"error: {message[:1000]}... ({counted(len(message) - 1000, 'character')} cut)",
    ]
