"""Help paragraphs joined for the terminal to wrap; example commands kept as written; every
option name whole at 80 columns (in-process; a command without arguments as a subprocess)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process

from bagkit.cli.help_text import reflow


def test_paragraph_lines_are_joined_and_indented_paragraphs_kept() -> None:
    text = """First line.

    Second paragraph, cut
    at the source's width.

    Examples:

      bagkit echo bag /imu -n 3
      bagkit echo bag /gps
    """
    assert reflow(text) == (
        "First line.\n\nSecond paragraph, cut at the source's width.\n\nExamples:\n\n"
        "\b\n  bagkit echo bag /imu -n 3\n  bagkit echo bag /gps"
    )


def _commands() -> list[tuple[list[str], list[str]]]:
    """Every command's and group's path (``["stats", "summary"]``, ``["stats"]``, ``[]`` for
    ``bagkit`` itself) and the names its help must show whole: its options, a group's commands,
    from the CLI (so a command added later is checked too)."""
    import typer

    from bagkit.cli.main import _COMMANDS, load_command

    found: list[tuple[list[str], list[str]]] = [([], sorted(_COMMANDS))]

    def walk(path: list[str], command: typer.core.TyperCommand | typer.core.TyperGroup) -> None:
        names = [o for p in command.params for o in (*p.opts, *p.secondary_opts) if "-" in o[:1]]
        if isinstance(command, typer.core.TyperGroup):
            visible = {name: sub for name, sub in command.commands.items() if not sub.hidden}
            found.append((path, [*names, *visible]))
            for name, sub in visible.items():
                walk([*path, name], sub)
            return
        found.append((path, names))

    for name in sorted(_COMMANDS):
        command = load_command(name)
        assert command is not None
        walk([name], command)  # type: ignore[arg-type]
    return found


COMMANDS = _commands()


@pytest.mark.parametrize(
    ("path", "options"), COMMANDS, ids=[" ".join(["bagkit", *p]) for p, _ in COMMANDS]
)
def test_help_at_80_columns_shows_every_option_name_whole(
    path: list[str], options: list[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    result = bagkit_in_process([*path, "-h"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert "…" not in result.stdout
    words = set(re.split(r"[\s,/=\[\]()]+", result.stdout))
    assert [o for o in [*options, "-h", "--help"] if o not in words] == []
    assert max(len(line) for line in result.stdout.splitlines()) <= 80


EXAMPLES_HEADINGS = ("  Example:", "  Examples:")


def _examples(help_text: str) -> list[str]:
    """The lines of the ``Examples:`` (or ``Example:``) section of a command's help."""
    lines = help_text.splitlines()
    heading = next((i for i, line in enumerate(lines) if line in EXAMPLES_HEADINGS), None)
    if heading is None:
        return []
    section = lines[heading + 1 :]
    return section[: next((i for i, line in enumerate(section) if line[:1].strip()), None)]


@pytest.mark.parametrize(
    ("path", "options"), COMMANDS, ids=[" ".join(["bagkit", *p]) for p, _ in COMMANDS]
)
def test_example_commands_are_printed_as_written_at_any_width(
    path: list[str], options: list[str], tmp_path: Path
) -> None:
    # A wrapped example cannot be pasted: click must not refill it on a narrow terminal.
    wide, narrow = (
        bagkit_in_process([*path, "-h"], tmp_path, env={"COLUMNS": columns}).stdout
        for columns in ("200", "80")
    )
    assert _examples(narrow) == _examples(wide)
    commands = [line.strip() for line in _examples(narrow) if line.strip()]
    assert "Example:" not in narrow.replace("\n  Example:\n", ""), "one Examples: section"
    assert all(
        line.startswith(("bagkit ", "|", "-")) or previous.endswith("\\")
        for previous, line in zip(["", *commands], commands, strict=False)
    ), commands


@pytest.mark.parametrize("command", ["replay", "play", "stats", "info"])
def test_a_command_without_arguments_prints_its_help(command: str) -> None:
    """No arguments: the help on stderr, exit 2 (as click does), never an internal error."""
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    result = subprocess.run(
        [bagkit, command], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(f"Usage: bagkit {command} ")


@pytest.mark.parametrize("command", ["info", "echo", "plot", "filter", "doctor", "recover"])
def test_a_bag_argument_names_every_kind_of_bag(command: str) -> None:
    # A user with ROS 1 or compressed rosbag2 bags reads the argument's help first.
    result = bagkit_in_process([command, "-h"], env={"COLUMNS": "200"})
    assert result.returncode == 0, result.stderr
    text = " ".join(result.stdout.split())
    assert ".mcap/.db3 file (or .zstd), or ROS 1 .bag file" in text
