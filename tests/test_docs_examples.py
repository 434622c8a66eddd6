"""The shell examples of README.md and docs/*.md, run as written on the fixtures.

Which lines are commands: in blocks fenced ```bash, ```sh or ```shell every line (``\\``
continues one); in ```console blocks the lines starting with ``$ `` (the others are output).
A command runs when it is a ``bagkit`` command (``.venv/bin/bagkit`` and ``VAR=value``
prefixes allowed) and, by rule:

- it needs no ROS graph: not ``record``, ``replay``/``play``, ``control``, ``golden record``,
  nor a live golden mode (those are the ROS tests' business);
- every bag or file it takes as an argument (or reads with ``--spec``) exists in its working
  directory. That directory holds a copy of ``fixtures/`` and, under the names the docs give
  a recording of the demo system (``flight1``, ``drive``, ``day1`` ...), bags made from the
  fixtures (:data:`RECORDINGS`;
  ``crashed`` is a fixture's copy cut short, as a killed recorder leaves it);
  paths elsewhere (``/data/fleet/``, ``bags.txt``) are not there and their commands are skipped.

What follows a pipe (``| jq ...``) is left out: the bagkit command runs alone, in this process
through the console script's entry (:func:`bagkit_runs.bagkit_in_process`: the same parsing,
exit status and output; the process boundary is tests/cli's); ``> FILE`` writes its output to
FILE. Each document's commands run in their order in one scratch directory (a command may read
what an earlier one wrote), never in the checkout. A command must exit 0, or N where its
comment says ``exit N``, without an ``error:`` line.
"""

from __future__ import annotations

import re
import shlex
import shutil
from dataclasses import dataclass
from pathlib import Path

import pytest
import typer
from bagkit_runs import bagkit_in_process

from bagkit.cli.main import app
from bagkit.storage.paths import UrlPath
from bagkit.storage.urls import is_url

ROOT = Path(__file__).resolve().parents[1]
BAG_ARGUMENTS = frozenset({"bag", "bags", "inputs"})
# Options that read a file an earlier command of the document may have written (under xdist
# the two can run on different workers, each with its own scratch directory).
INPUT_OPTIONS = frozenset({"spec"})
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
# The names the docs give a recording of the demo system -> the fixture it is made from.
RECORDINGS = {
    "flight1": "nominal",
    "drive": "nominal",
    "golden": "nominal",
    "candidate": "faults",
    "golden_bag": "nominal",
    "candidate_bag": "nominal",
    "day1": "nominal",
    "day2": "faults",
    "part1": "nominal",
    "part2": "faults",
    "incident": "faults",
}
SHELL_FENCES = {"bash", "sh", "shell"}
NEEDS_ROS = {("record",), ("replay",), ("play",), ("control",), ("golden", "record")}


@dataclass(frozen=True)
class Example:
    """One command of a document: where it is, its arguments after ``bagkit``, its comment."""

    document: Path
    line: int
    args: tuple[str, ...]
    comment: str
    stdout: str | None = None
    """The file ``> FILE`` sends the output to."""

    def __str__(self) -> str:
        return f"{self.document.name}:{self.line}"


def _commands(document: Path) -> list[Example]:
    """The bagkit command lines of a document's shell blocks."""
    examples = []
    fence: str | None = None
    pending: tuple[int, str] | None = None
    for number, raw in enumerate(document.read_text().splitlines(), 1):
        opening = re.match(r"\s*```(\S*)", raw)
        if opening:
            fence = opening.group(1) if fence is None else None
            continue
        if fence == "console" and raw.startswith("$ "):
            line = raw[2:]
        elif fence in SHELL_FENCES:
            line = raw
        else:
            continue
        start, text = pending if pending else (number, "")
        text += line.rstrip().removesuffix("\\")
        if line.rstrip().endswith("\\"):
            pending = (start, text + " ")
            continue
        pending = None
        example = _parse(document, start, text)
        if example is not None:
            examples.append(example)
    return examples


def _parse(document: Path, line: int, text: str) -> Example | None:
    command, _, comment = text.partition(" #")
    tokens = shlex.split(command.split(" | ")[0])
    while tokens and re.fullmatch(r"[A-Z_]+=\S*", tokens[0]):
        tokens.pop(0)
    if not tokens or Path(tokens[0]).name != "bagkit":
        return None
    stdout = None
    if len(tokens) > 2 and tokens[-2] == ">":
        stdout, tokens = tokens[-1], tokens[:-2]
    return Example(document, line, tuple(tokens[1:]), comment, stdout)


EXAMPLES = [example for document in DOCUMENTS for example in _commands(document)]


def _arguments(args: tuple[str, ...]) -> tuple[list[str], dict[str, object], list[Path]]:
    """The command's words (``stats summary``), its parsed options and its path arguments."""
    command = typer.main.get_command(app)
    words: list[str] = []
    rest = list(args)
    while True:
        ctx = command.make_context("bagkit", list(rest), resilient_parsing=True)
        if not hasattr(command, "get_command"):
            break
        # The vendored click keeps a group's subcommand and its arguments here.
        sub = [*getattr(ctx, "_protected_args", []), *ctx.args]
        if not sub:
            break
        words.append(sub[0])
        command, rest = command.get_command(ctx, sub[0]), sub[1:]
    paths = [
        value
        for param in command.params
        if param.param_type_name == "argument"
        for value in (
            ctx.params.get(param.name or "")
            if isinstance(ctx.params.get(param.name or ""), list | tuple)
            else [ctx.params.get(param.name or "")]
        )
        # A bag argument typed str (info's, for its start-up time) is a path all the same.
        if isinstance(value, Path | UrlPath)
        or (param.name in BAG_ARGUMENTS and isinstance(value, str))
    ]
    paths += [ctx.params[name] for name in INPUT_OPTIONS if isinstance(ctx.params.get(name), Path)]
    return words, ctx.params, paths


@pytest.fixture(scope="session")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory with fixtures/ and the docs' recordings, made once."""
    template = tmp_path_factory.mktemp("docs_template")
    shutil.copytree(ROOT / "fixtures", template / "fixtures")
    for name, fixture in RECORDINGS.items():
        # In this process: the recordings are the examples' inputs, not what they check.
        source = template / "fixtures" / fixture / "golden"
        done = bagkit_in_process(["merge", source, "-o", name], cwd=template)
        assert done.returncode == 0, done.stderr
    # "crashed": a recording killed before its summary was written (its file cut where the
    # summary starts, at the Data End record: its one chunk is whole, so recover exits 0).
    shutil.copytree(template / "fixtures" / "nominal" / "golden", template / "crashed")
    (mcap,) = (template / "crashed").glob("*.mcap")
    data, pos = mcap.read_bytes(), 8
    while data[pos] != 0x0F:  # the Data End record
        pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
    with mcap.open("r+b") as file:
        file.truncate(pos)
    return template


@pytest.fixture(scope="session")
def workdirs(recordings: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[Path, Path]:
    """One scratch working directory per document, made on first use."""

    class PerDocument(dict[Path, Path]):
        def __missing__(self, document: Path) -> Path:
            made = tmp_path_factory.mktemp(document.stem) / "work"
            shutil.copytree(recordings, made)
            self[document] = made
            return made

    return PerDocument()


@pytest.mark.parametrize("example", EXAMPLES, ids=str)
def test_example_runs_as_written(example: Example, workdirs: dict[Path, Path]) -> None:
    words, params, paths = _arguments(example.args)
    # Parsed without defaults (resilient parsing): no --mode is golden's default, lockstep.
    live_mode = words[:1] == ["golden"] and params.get("mode") not in (None, "lockstep")
    if tuple(words) in NEEDS_ROS or live_mode:
        pytest.skip(f"needs a ROS graph: bagkit {' '.join(words)}")
    if params.get("live"):
        pytest.skip("needs a ROS graph: --live")
    workdir = workdirs[example.document]
    # A bag in storage (a URL) is never reached from here: tests/storage reads URLs.
    missing = [str(path) for path in paths if is_url(path) or not (workdir / path).exists()]
    if missing:
        pytest.skip(f"not among the fixtures: {', '.join(missing)}")
    expected = re.search(r"\bexits? (\d+)\b", example.comment)
    done = bagkit_in_process(list(example.args), cwd=workdir)
    assert done.returncode == (int(expected.group(1)) if expected else 0), done.stderr
    assert "error:" not in done.stderr, done.stderr
    if example.stdout is not None:
        (workdir / example.stdout).write_text(done.stdout)
