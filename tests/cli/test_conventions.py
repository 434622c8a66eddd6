"""What every command shares: -h, list options, one meaning per short flag, formats offered
only where they work, shell completion, and commands imported only when they run."""

from __future__ import annotations

import functools
import json
import os
import struct
import subprocess
import sys
from pathlib import Path
from unittest import mock

import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess

from bagkit.bag import BagWriter, TopicInfo
from bagkit.cli.main import _COMMANDS
from bagkit.cli.option_parsing import expand_multi_value_options, split_list

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
FLOAT64 = "std_msgs/msg/Float64"


def _run(
    *args: str, columns: int = 100, in_subprocess: bool = False
) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` at ``columns``: in this process, unless ``in_subprocess`` or the command
    is ``record`` or ``play`` (they load rclpy)."""
    with mock.patch.dict(os.environ, {"COLUMNS": str(columns)}):
        if in_subprocess or args[0] in ("record", "play"):
            return bagkit_subprocess(list(args), Path.cwd())
        return bagkit_in_process(list(args), Path.cwd())


def _run_in_python(argv: list[str], then: str) -> subprocess.CompletedProcess[str]:
    """Run ``argv`` as the console script does in a fresh interpreter, then the code ``then``.

    The exit status is printed as ``EXIT <code>`` on stderr.
    """
    code = (
        f"import sys; sys.argv = {argv!r}\n"
        "from bagkit.cli.launch import run\n"
        "try:\n    run()\nexcept SystemExit as exc:\n    print('EXIT', exc.code, file=sys.stderr)\n"
        f"{then}"
    )
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )


def test_split_list_takes_repeated_values_and_comma_lists() -> None:
    assert split_list(None) == []
    assert split_list(["/a,/b", "/c", " /d , ,"]) == ["/a", "/b", "/c", "/d"]


def test_several_values_after_one_flag_become_repetitions() -> None:
    options = frozenset({"--topics", "--exclude-topics"})
    args = ["--topics", "/a", "/b", "-o", "out", "--exclude-topics", "/c", "/d", "--all"]
    assert expand_multi_value_options(args, options) == [
        *["--topics", "/a", "--topics", "/b", "-o", "out"],
        *["--exclude-topics", "/c", "--exclude-topics", "/d", "--all"],
    ]
    # A positional before any such option, and values of other options, stay as they are.
    assert expand_multi_value_options(["/x", "-o", "a", "b"], options) == ["/x", "-o", "a", "b"]
    # After `--`, nothing is rewritten.
    assert expand_multi_value_options(["--", "--topics", "/a", "/b"], options) == [
        *["--", "--topics", "/a", "/b"]
    ]


def test_an_existing_path_ends_the_values_until_the_bag_is_given(tmp_path: Path) -> None:
    options = frozenset({"--topics"})
    bag = str(tmp_path)
    expand = functools.partial(
        expand_multi_value_options, options=options, value_options=frozenset({"--rate"})
    )
    # The bag after the topics is the positional argument...
    assert expand(["--topics", "/a", "/b", bag], path_ends_values=True) == [
        *["--topics", "/a", "--topics", "/b", bag]
    ]
    # ...also after an option's value, which is not taken for the bag...
    assert expand(["--rate", "2", "--topics", "/a", bag], path_ends_values=True) == [
        *["--rate", "2", "--topics", "/a", bag]
    ]
    # ...but not once the bag was given, nor for commands without a bag argument.
    assert expand([bag, "--topics", "/a", bag], path_ends_values=True) == [
        *[bag, "--topics", "/a", "--topics", bag]
    ]
    assert expand(["--topics", "/a", bag]) == ["--topics", "/a", "--topics", bag]


@pytest.mark.parametrize("command", sorted(_COMMANDS))
@pytest.mark.parametrize("flag", ["-h", "--help"])
def test_every_command_answers_h_and_help(command: str, flag: str) -> None:
    # The first command's -h as a shell runs it, the process boundary once.
    shell = (command, flag) == (min(_COMMANDS), "-h")
    result = _run(command, flag, columns=80, in_subprocess=shell)
    assert result.returncode == 0, result.stderr
    assert f"bagkit {command}" in result.stdout and "Usage" in result.stdout
    assert max(len(line) for line in result.stdout.splitlines()) <= 80
    # The description's paragraphs wrap at the terminal's width, not at the source's lines:
    # within a paragraph only the last line is short.
    lines = [line.rstrip() for line in result.stdout.splitlines()]
    start = next(i for i, line in enumerate(lines) if "Usage:" in line) + 1
    end = next(i for i, line in enumerate(lines) if line in ("Arguments:", "Options:"))
    paragraphs = "\n".join(lines[start:end]).split("\n\n")
    stubs = [
        line
        for paragraph in paragraphs
        for line in paragraph.strip("\n").splitlines()[:-1]
        if len(line) < 50
    ]
    assert not stubs, f"lines cut short in the help of {command}: {stubs}"


def test_top_level_help_lists_every_command_without_importing_them() -> None:
    result = _run_in_python(
        ["bagkit", "--help"],
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'pandas', "
        "'rich', 'pydantic', 'rclpy') or m.startswith('bagkit.cli.') and m not in "
        "('bagkit.cli.main', 'bagkit.cli.common', 'bagkit.cli.interrupts', "
        "'bagkit.cli.launch', 'bagkit.cli.plain_params', 'bagkit.cli.help_text'))\n"
        "print('HEAVY', heavy, file=sys.stderr)\n",
    )
    assert "HEAVY []" in result.stderr and "EXIT 0" in result.stderr, result.stderr
    for command in _COMMANDS:
        assert f"\n  {command} " in result.stdout


def test_info_imports_neither_pydantic_nor_other_commands(tmp_path: Path) -> None:
    bag = _bag(tmp_path)
    code = (
        f"import sys; sys.argv = ['bagkit', 'info', {str(bag)!r}]\n"
        "from bagkit.cli.launch import run\n"
        "try:\n    run()\nexcept SystemExit:\n    pass\n"
        "print('LOADED', sorted(m for m in sys.modules if m.startswith(('pydantic', "
        "'pandas', 'bagkit.cli.stats', 'bagkit.cli.record', 'bagkit.compare'))), file=sys.stderr)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert "LOADED []" in result.stderr


def test_shell_completion_is_available() -> None:
    # typer detects the shell from the parent process, as at a prompt ("; true": bash must
    # not exec bagkit in its place).
    result = subprocess.run(
        ["bash", "-c", f"{BAGKIT} --show-completion; true"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    assert "complete -o default -F _bagkit_completion bagkit" in result.stdout, result.stderr


def _bag(tmp_path: Path) -> Path:
    path = tmp_path / "lists"
    payload = b"\x00\x01\x00\x00" + struct.pack("<d", 1.5)  # CDR of Float64(1.5)
    with BagWriter(path) as bag:
        for topic in ("/a", "/b", "/c"):
            bag.add_topic(TopicInfo(topic, FLOAT64))
        for i in range(10):
            for topic in ("/a", "/b", "/c"):
                bag.write(topic, payload, log_time=1_000_000_000 + i * 100_000_000)
    return path


def test_stats_summary_takes_comma_lists_as_repeated_options(tmp_path: Path) -> None:
    bag = str(_bag(tmp_path))
    comma = _run("stats", "summary", bag, "-t", "/a,/c", "--format", "json")
    repeated = _run("stats", "summary", bag, "-t", "/a", "--topics", "/c", "--format", "json")
    assert comma.returncode == 0, comma.stderr
    topics = [t["topic"] for t in json.loads(comma.stdout)["topics"]]
    assert topics == ["/a", "/c"]
    assert json.loads(comma.stdout) == json.loads(repeated.stdout)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        # Reports offer table and json only; csv is not listed, so it is a usage error.
        (["compare", "x", "y", "--format", "csv"], "'csv' is not one of 'table', 'json'."),
        (["record", "-a", "--format", "csv"], "'csv' is not one of 'table', 'json'."),
        (["info", "x", "--format", "csv"], "'csv' is not one of 'table', 'json'."),
        # -f is --fields wherever it exists; no command takes -f for --format.
        (["record", "-a", "-f", "json"], "No such option: -f"),
        (["info", "x", "-f", "json"], "No such option: -f"),
        (["compare", "x", "y", "-f", "json"], "No such option: -f"),
    ],
)
def test_formats_and_short_flags(args: list[str], expected: str) -> None:
    result = _run(*args)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("error:") and expected in line


def test_help_of_reports_lists_only_working_formats() -> None:
    for command in ("record", "info", "compare"):
        out = _run(command, "--help").stdout
        assert "table|json" in out.replace(" ", "") and "csv" not in out, command


@pytest.mark.parametrize(
    "args",
    [
        ["stats", "summary", "BAG", "--start", "0.1", "--workers", "0"],
        ["echo", "BAG", "/a", "-n", "2"],
        ["echo", "BAG", "/a", "-n", "-1"],  # an out-of-range number: our message, no pydantic
    ],
)
def test_number_options_are_parsed_without_pydantic(tmp_path: Path, args: list[str]) -> None:
    # typer parses through pydantic, whose import costs every command tens of milliseconds.
    argv = ["bagkit", *(str(_bag(tmp_path)) if a == "BAG" else a for a in args)]
    result = _run_in_python(argv, "print('PYDANTIC', 'pydantic' in sys.modules, file=sys.stderr)\n")
    assert "PYDANTIC False" in result.stderr
    expected = 2 if "-1" in args else 0
    assert f"EXIT {expected}" in result.stderr, result.stderr


def test_filter_and_convert_declare_their_selection_options_once() -> None:
    """The topic rules and --where of filter and convert are one declaration (one help)."""
    from bagkit.cli.main import load_command

    names = ("--topics", "--regex", "--exclude-topics", "--exclude-regex", "--where")

    def declared(command: str) -> dict[str, tuple[object, ...]]:
        loaded = load_command(command)
        assert loaded is not None
        return {
            p.opts[0]: (tuple(p.opts), p.help, p.metavar)  # type: ignore[attr-defined]
            for p in loaded.params
            if p.opts[0] in names
        }

    filter_options = declared("filter")
    assert sorted(filter_options) == sorted(names)
    assert all(help_ for _, help_, _ in filter_options.values())
    assert declared("convert") == filter_options


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["filter", "bag"], "error: Missing option '--output' / '-o'."),
        (["filter", "-o", "out"], "error: Missing argument 'bag'."),
        (["play", "x", "--rate", "abc"], "error: Invalid value for '--rate' / '-r': Input should"),
    ],
)
def test_plain_parameters_word_their_errors_as_click(args: list[str], expected: str) -> None:
    """Parameters processed without typer's pydantic adapter (plain_params) still say what is
    missing or wrong as click says it, in one line, exit 2."""
    result = _run(*args)
    assert result.returncode == 2
    (line,) = result.stderr.splitlines()
    assert line.startswith(expected), line
