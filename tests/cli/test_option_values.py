"""Every value option of every command that reads or rewrites bags, given hostile values: the
command ends with at most one ``error:`` line and a meaningful exit status, never an internal
error (70) or a traceback. Run in-process (about 400 runs), from a scratch working directory."""

from __future__ import annotations

import contextlib
import io
import struct
from pathlib import Path

import pytest
from typer.core import TyperGroup, TyperOption

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.cli.common import run_app
from bagkit.cli.main import app, load_command

HOSTILE = ["nan", "inf", "-1", "1e400", "", "abc", "99999999999999999999"]
# Options that would start a local Dask cluster or reach for a scheduler: their values are
# checked by tests/fleet; a sweep must not start 10^20 workers.
NOT_SWEPT = {"--workers", "--scheduler"}


def _commands(bag: str, out: Path) -> dict[str, list[str]]:
    """A valid invocation of each command (on a 10-message bag): the sweep adds one option."""
    return {
        "info": ["info", bag],
        "stats summary": ["stats", "summary", bag],
        "echo": ["echo", bag, "/a"],
        "export": ["export", bag, "-o", str(out / "export")],
        "plot": ["plot", bag, "/a:data", "-o", str(out / "plot.png")],
        "doctor": ["doctor", bag],
        "filter": ["filter", bag, "-o", str(out / "filtered"), "--force"],
        "merge": ["merge", bag, "-o", str(out / "merged"), "--force"],
        "recover": ["recover", bag, "-o", str(out / "recovered"), "--force"],
        "compare": ["compare", bag, bag],
    }


def _value_options(path: list[str]) -> list[str]:
    command = load_command(path[0])
    for name in path[1:]:
        assert isinstance(command, TyperGroup)
        command = command.commands[name]
    assert command is not None
    return [
        max(param.opts, key=len)
        for param in command.params
        if isinstance(param, TyperOption) and not param.is_flag and not param.count
    ]


def _run(args: list[str]) -> tuple[object, str]:
    out, err = io.StringIO(), io.StringIO()
    code: object = None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            run_app(app, args)
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue()


@pytest.fixture
def bag(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    # A scratch working directory: a value like "" or "." names it, and must not harm it.
    scratch = tmp_path / "cwd"
    scratch.mkdir()
    monkeypatch.chdir(scratch)
    path = tmp_path / "bag"
    payload = b"\x00\x01\x00\x00" + struct.pack("<d", 1.5)  # CDR of Float64(1.5)
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/a", "std_msgs/msg/Float64"))
        for i in range(10):
            writer.write("/a", payload, log_time=1_000_000_000 + i * 100_000_000)
    return str(path)


def test_hostile_option_values_end_in_one_error_line(bag: str, tmp_path: Path) -> None:
    broken = []
    runs = 0
    for name, base in _commands(bag, tmp_path).items():
        options = [o for o in _value_options(name.split()) if o not in NOT_SWEPT]
        assert options, name
        for option in options:
            for value in HOSTILE:
                code, err = _run([*base, option, value])
                runs += 1
                errors = [line for line in err.splitlines() if line.startswith("error:")]
                if code not in (0, 1, 2) or len(errors) > 1 or "internal error" in err:
                    broken.append(f"{name} {option} {value!r}: exit {code}: {err.strip()[:200]}")
                if "Traceback" in err:
                    broken.append(f"{name} {option} {value!r}: a traceback")
    assert runs > 300
    assert not broken, "\n".join(broken)
    with BagReader(bag) as reader:  # what was recorded stays readable
        assert reader.message_count == 10
