"""Fixture specs: how the system under test is named, and a clean error for each bad spec."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml
from bagkit_runs import bagkit_in_process

from bagkit.regression.errors import SpecError
from bagkit.regression.spec import load_spec

BASE = {"inputs": ["/value"], "outputs": ["/doubled"], "processor": "pkg.core:make"}


def spec_at(tmp_path: Path, **changes: object) -> Path:
    data = {**BASE, **changes}
    data = {k: v for k, v in data.items() if v is not None}
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(data))
    return tmp_path


def test_commands_resolve_python_console_scripts_and_the_fixture(tmp_path: Path) -> None:
    spec = load_spec(
        spec_at(
            tmp_path,
            launch="python -m pkg.node --ros-args -p use_sim_time:=true",
            record_launch=[
                "bagkit info {fixture}/golden",
                ["my-node", "--config", "{fixture}/c.yaml"],
            ],
        )
    )
    assert spec.launch == (
        (sys.executable, "-m", "pkg.node", "--ros-args", "-p", "use_sim_time:=true"),
    )
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    assert spec.record_launch == (
        (bagkit, "info", f"{tmp_path}/golden"),
        ("my-node", "--config", f"{tmp_path}/c.yaml"),  # not installed here: left to PATH
    )
    assert spec.modes == ("lockstep", "live")
    assert spec.subscription_counts() == {"/value": 1, "/clock": 1}
    assert spec.live_rate == 1.0


def test_defaults_and_explicit_settings(tmp_path: Path) -> None:
    spec = load_spec(
        spec_at(tmp_path, wait_for={"/value": 3, "/clock": 2}, live_rate=4, launch="node")
    )
    assert spec.subscription_counts() == {"/value": 3, "/clock": 2}
    assert spec.live_rate == 4.0
    relative = load_spec(spec_at(tmp_path, outputs=["doubled", "/also"]))
    assert relative.outputs == ("/doubled", "/also")
    only = load_spec(spec_at(tmp_path, launch="node", modes=["lockstep"]))
    assert only.modes == ("lockstep",)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"processor": None}, "no system under test"),
        ({"processor": "pkg.core"}, "module.path:function"),
        ({"inputs": []}, "inputs must be a non-empty list"),
        ({"outputs": ["/"]}, "must hold topic names"),
        ({"launch": 3}, "launch must be a command line"),
        ({"launch": [""]}, "launch must be a command line"),
        ({"live_rate": "fast"}, "must be numbers"),
        ({"live_rate": 0}, "must be positive"),
        ({"wait_for": {"/value": -1}}, "subscription counts"),
        ({"modes": ["replay"]}, "modes must be a list of lockstep, live"),
        ({"modes": ["live"]}, "mode live needs launch"),
        ({"compare": {"atol": -1}}, "lockstep"),
        ({"processor_args": [1, 2]}, "processor_args must be a mapping"),
    ],
)
def test_bad_specs_are_spec_errors(
    tmp_path: Path, changes: dict[str, object], message: str
) -> None:
    with pytest.raises(SpecError, match=message):
        load_spec(spec_at(tmp_path, **changes))


def test_unreadable_files_are_spec_errors(tmp_path: Path) -> None:
    with pytest.raises(SpecError, match="cannot read fixture spec"):
        load_spec(tmp_path / "missing")
    (tmp_path / "spec.yaml").write_text("inputs: [unclosed\n")
    with pytest.raises(SpecError, match="not valid YAML"):
        load_spec(tmp_path)
    (tmp_path / "spec.yaml").write_bytes(b"inputs: \xff\xfe\n")
    with pytest.raises(SpecError, match="not valid YAML"):
        load_spec(tmp_path)
    (tmp_path / "spec.yaml").write_text("- a list\n")
    with pytest.raises(SpecError, match="expected a mapping"):
        load_spec(tmp_path)


def test_a_deeply_nested_spec_is_one_error(tmp_path: Path) -> None:
    # Loaded without limits, 30,000 '[' were a RecursionError (exit 70); libyaml's C composer
    # can end the process instead.
    (tmp_path / "spec.yaml").write_text("inputs: " + "[" * 30_000 + "]" * 30_000 + "\n")
    for command in ("check", "migrate"):
        result = bagkit_in_process(["golden", command, tmp_path])
        assert result.returncode == 2, result.stderr
        (line,) = result.stderr.strip().splitlines()
        assert line.startswith("error:") and "nested deeper than 64 levels" in line
