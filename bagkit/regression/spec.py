"""Fixture specs: the system under test, what its golden bag holds, how runs are judged.

A fixture is a directory holding ``spec.yaml`` and the golden bag ``golden/``. The spec names
the system under test in one or both of two ways: ``processor`` (a factory of Python
processors, run in lockstep) and ``launch`` (command lines that start the nodes with
``use_sim_time``, run live over DDS). See docs/regression.md for every key.
"""

from __future__ import annotations

import shlex
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bagkit.bag import safe_yaml
from bagkit.compare import CompareOptions, options_from_mapping
from bagkit.compare.errors import CompareError
from bagkit.health.spec import HealthSpec
from bagkit.health.spec import SpecError as HealthSpecError
from bagkit.regression.errors import SpecError
from bagkit.regression.services import service_ignore_fields
from bagkit.selection.services import event_topic
from bagkit.selection.topics import absolute_topic_name

SPEC_FILE = "spec.yaml"
BAG_DIR = "golden"
MODES = ("lockstep", "live")
MAX_SPEC_BYTES = 1_000_000

Command = tuple[str, ...]


@dataclass(frozen=True, slots=True)
class FixtureSpec:
    """A golden fixture: ``<dir>/spec.yaml`` beside the bag ``<dir>/golden``.

    Attributes:
        name: the fixture's directory name.
        directory: the fixture directory.
        description: one line on what the recording shows.
        duration_s: how long ``bagkit golden record`` records the live system.
        inputs: the topics replayed into the system.
        outputs: the topics the system publishes, compared with the golden.
        processor: ``module:factory`` of the lockstep processors, or None.
        processor_args: keyword arguments of the factory.
        launch: command lines starting the nodes under test with use_sim_time (live mode).
        record_launch: command lines starting the whole system on the wall clock, sources of
            the inputs included (``bagkit golden record``).
        record_topics: further topics recorded into the golden (ground truth, say).
        wait_for: topic -> subscriptions to wait for before replaying (default: one on each
            input topic and on /clock).
        live_rate: replay rate of live mode (1 = real time).
        modes: the modes this fixture runs in (default: those the spec describes).
        lockstep: the raw ``compare:`` section for lockstep runs.
        live: the raw ``live_compare:`` section for live replays through DDS.
        services: services whose recorded requests are sent to the system under test (live)
            or handed to the processors' ``on_request`` (lockstep); their event topics
            (``NAME/_service_event``) are among ``outputs``.
        health: the ``health:`` section, a contract (``bagkit check``'s) that the golden and
            every run's outputs must keep (on a run: the contract's topics among ``outputs``).
    """

    name: str
    directory: Path
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    description: str = ""
    duration_s: float = 30.0
    processor: str | None = None
    processor_args: Mapping[str, Any] = field(default_factory=dict)
    launch: tuple[Command, ...] = ()
    record_launch: tuple[Command, ...] = ()
    record_topics: tuple[str, ...] = ()
    wait_for: Mapping[str, int] = field(default_factory=dict)
    live_rate: float = 1.0
    modes: tuple[str, ...] = ()
    lockstep: Mapping[str, Any] = field(default_factory=dict)
    live: Mapping[str, Any] = field(default_factory=dict)
    services: tuple[str, ...] = ()
    health: HealthSpec | None = None

    @property
    def bag(self) -> Path:
        """The golden bag: recorded inputs and the expected outputs."""
        return self.directory / BAG_DIR

    def compare_options(self, mode: str = "lockstep", **overrides: Any) -> CompareOptions:
        """Comparison options for ``mode`` (``lockstep`` or ``live``) over the output topics."""
        section = self.live if mode == "live" else self.lockstep
        if self.services:
            ignored = list(section.get("ignore_fields") or [])
            section = {**section, "ignore_fields": ignored + service_ignore_fields(self.services)}
        try:
            return options_from_mapping(section, topics=self.outputs, **overrides)
        except CompareError as exc:
            raise SpecError(f"{self.directory / SPEC_FILE}: {mode}: {exc}") from exc

    def subscription_counts(self) -> dict[str, int]:
        """What live mode waits for in the ROS graph before it replays."""
        return dict(self.wait_for) or {**dict.fromkeys(self.inputs, 1), "/clock": 1}


def _topics(
    data: Mapping[str, Any], key: str, where: Path, *, required: bool = True
) -> tuple[str, ...]:
    value = data.get(key, None if required else [])
    if not isinstance(value, list) or (required and not value):
        raise SpecError(
            f"{where}: {key} must be a {'non-empty ' if required else ''}list of topics"
        )
    if not all(isinstance(t, str) and t.strip("/") for t in value):
        raise SpecError(f"{where}: {key} must hold topic names")
    return tuple(absolute_topic_name(t) for t in value)


def resolve_command(command: Sequence[str], directory: Path) -> Command:
    """``command`` with ``{fixture}`` replaced by the fixture directory and a leading
    ``python`` (or a console script installed beside it) resolved to this environment."""
    args = [arg.replace("{fixture}", str(directory)) for arg in command]
    if args[0] in {"python", "python3"}:
        args[0] = sys.executable
    elif "/" not in args[0] and Path(sys.executable).with_name(args[0]).exists():
        args[0] = str(Path(sys.executable).with_name(args[0]))
    return tuple(args)


def _commands(data: Mapping[str, Any], key: str, where: Path) -> tuple[Command, ...]:
    value = data.get(key)
    if value is None:
        return ()
    items = value if isinstance(value, list) else [value]
    commands = []
    for item in items:
        args = shlex.split(item) if isinstance(item, str) else item
        if not isinstance(args, list) or not args or not all(isinstance(a, str) for a in args):
            raise SpecError(f"{where}: {key} must be a command line or a list of them")
        commands.append(resolve_command(args, where.parent))
    return tuple(commands)


def _mapping(data: Mapping[str, Any], key: str, where: Path) -> dict[str, Any]:
    value = data.get(key) or {}
    if not isinstance(value, Mapping):
        raise SpecError(f"{where}: {key} must be a mapping")
    return dict(value)


def _wait_for(data: Mapping[str, Any], where: Path) -> dict[str, int]:
    counts = _mapping(data, "wait_for", where)
    if not all(isinstance(n, int) and n >= 0 for n in counts.values()):
        raise SpecError(f"{where}: wait_for must map topics to subscription counts")
    return counts


def _modes(data: Mapping[str, Any], where: Path, has: dict[str, bool]) -> tuple[str, ...]:
    value = data.get("modes", [m for m in MODES if has[m]])
    if not value and not data.get("modes"):
        raise SpecError(f"{where}: no system under test: give processor and/or launch")
    if not isinstance(value, list) or not value or any(m not in MODES for m in value):
        raise SpecError(f"{where}: modes must be a list of {', '.join(MODES)}")
    for mode in value:
        if not has[mode]:
            key = "processor" if mode == "lockstep" else "launch"
            raise SpecError(f"{where}: mode {mode} needs {key}")
    return tuple(value)


def _read(file: Path) -> tuple[Mapping[str, Any], str]:
    try:
        if file.stat().st_size > MAX_SPEC_BYTES:
            raise SpecError(f"{file} is larger than {MAX_SPEC_BYTES} bytes")
        text = file.read_text()
        data = safe_yaml.load(text)  # depth-limited: a fixture spec may come from anyone
    except OSError as exc:
        raise SpecError(f"cannot read fixture spec {file}: {exc.strerror}") from exc
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise SpecError(f"{file} is not valid YAML: {exc}") from exc
    if not isinstance(data, Mapping):
        raise SpecError(f"{file}: expected a mapping")
    return data, text


def _health(text: str, file: Path) -> HealthSpec | None:
    try:
        return HealthSpec.parse_section(text, "health", str(file))
    except HealthSpecError as exc:
        raise SpecError(str(exc)) from None


def load_spec(path: Path) -> FixtureSpec:
    """Read a fixture spec from its directory or its ``spec.yaml``.

    Raises:
        SpecError: the file is missing or invalid.
    """
    file = path / SPEC_FILE if path.is_dir() else path
    data, text = _read(file)
    processor = data.get("processor")
    if processor is not None and (not isinstance(processor, str) or ":" not in processor):
        raise SpecError(f"{file}: processor must read module.path:function, not {processor!r}")
    launch = _commands(data, "launch", file)
    try:
        live_rate = float(data.get("live_rate", 1.0))
        duration = float(data.get("duration", 30.0))
    except (TypeError, ValueError) as exc:
        raise SpecError(f"{file}: live_rate and duration must be numbers") from exc
    if not 0 < live_rate < 1e6 or not 0 < duration < 1e6:
        raise SpecError(f"{file}: live_rate and duration must be positive")
    services = _topics(data, "services", file, required=False)
    spec = FixtureSpec(
        name=file.parent.name,
        directory=file.parent,
        description=str(data.get("description", "")),
        duration_s=duration,
        inputs=_topics(data, "inputs", file),
        outputs=tuple(
            dict.fromkeys(
                [
                    *_topics(data, "outputs", file, required=not services),
                    *map(event_topic, services),
                ]
            )
        ),
        processor=processor,
        processor_args=_mapping(data, "processor_args", file),
        launch=launch,
        record_launch=_commands(data, "record_launch", file),
        record_topics=_topics(data, "record_topics", file, required=False),
        wait_for=_wait_for(data, file),
        live_rate=live_rate,
        modes=_modes(data, file, {"lockstep": processor is not None, "live": bool(launch)}),
        lockstep=_mapping(data, "compare", file),
        live=_mapping(data, "live_compare", file),
        services=services,
        health=_health(text, file),
    )
    spec.compare_options("lockstep")  # fail now, not in the middle of a run
    spec.compare_options("live")
    return spec


def find_fixtures(root: Path) -> list[FixtureSpec]:
    """Every fixture under ``root`` (directories holding a ``spec.yaml``), by name."""
    return [load_spec(p.parent) for p in sorted(root.rglob(SPEC_FILE))]
