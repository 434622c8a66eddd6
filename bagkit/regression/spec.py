"""Fixture specs: what a golden bag holds and how its replays are judged (``spec.yaml``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bagkit.compare import CompareOptions, options_from_mapping
from bagkit.compare.errors import CompareError
from bagkit.regression.errors import SpecError
from bagkit.regression.lockstep import NodeUnderTest
from fusion.params import flatten

SPEC_FILE = "spec.yaml"
BAG_DIR = "golden"


@dataclass(frozen=True, slots=True)
class FixtureSpec:
    """A golden fixture: ``fixtures/<name>/spec.yaml`` beside the bag ``fixtures/<name>/golden``.

    Attributes:
        name: the fixture's directory name.
        directory: the fixture directory.
        description: one line on what the flight shows.
        duration_s: how long the live system is recorded when the fixture is re-recorded.
        scenario: parameter overrides of the sensor publisher (seed, trajectory, faults),
            dotted names (nested in the file, as in a ROS 2 parameter file).
        nodes: the nodes under test with their parameter overrides (dotted names).
        inputs: the topics replayed into the nodes.
        outputs: the topics the nodes publish, compared with the golden.
        lockstep: the raw ``compare:`` section for lockstep runs.
        live: the raw ``live_compare:`` section for live replays through DDS.
    """

    name: str
    directory: Path
    description: str
    duration_s: float
    scenario: Mapping[str, object]
    nodes: tuple[NodeUnderTest, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    lockstep: Mapping[str, Any] = field(default_factory=dict)
    live: Mapping[str, Any] = field(default_factory=dict)

    @property
    def bag(self) -> Path:
        """The golden bag: live-recorded inputs and the expected outputs (from lockstep)."""
        return self.directory / BAG_DIR

    def compare_options(self, mode: str = "lockstep", **overrides: Any) -> CompareOptions:
        """Comparison options for ``mode`` (``lockstep`` or ``live``) over the output topics."""
        section = self.live if mode == "live" else self.lockstep
        try:
            return options_from_mapping(section, topics=self.outputs, **overrides)
        except CompareError as exc:
            raise SpecError(f"{self.directory / SPEC_FILE}: {mode}: {exc}") from exc


def _topics(data: Mapping[str, Any], key: str, where: Path) -> tuple[str, ...]:
    value = data.get(key)
    if not isinstance(value, list) or not value or not all(isinstance(t, str) for t in value):
        raise SpecError(f"{where}: {key} must be a non-empty list of topic names")
    return tuple(value)


def load_spec(path: Path) -> FixtureSpec:
    """Read a fixture spec from its directory or its ``spec.yaml``.

    Raises:
        SpecError: the file is missing or invalid.
    """
    file = path / SPEC_FILE if path.is_dir() else path
    try:
        data = yaml.safe_load(file.read_text())
    except OSError as exc:
        raise SpecError(f"cannot read fixture spec {file}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise SpecError(f"{file} is not valid YAML: {exc}") from exc
    if not isinstance(data, Mapping):
        raise SpecError(f"{file}: expected a mapping")
    nodes = data.get("nodes")
    if not isinstance(nodes, Mapping) or not nodes:
        raise SpecError(f"{file}: nodes must map node names to parameter overrides")
    spec = FixtureSpec(
        name=file.parent.name,
        directory=file.parent,
        description=str(data.get("description", "")),
        duration_s=float(data.get("duration", 30.0)),
        scenario=flatten(data.get("scenario") or {}),
        nodes=tuple(NodeUnderTest(str(n), flatten(p or {})) for n, p in nodes.items()),
        inputs=_topics(data, "inputs", file),
        outputs=_topics(data, "outputs", file),
        lockstep=dict(data.get("compare") or {}),
        live=dict(data.get("live_compare") or {}),
    )
    spec.compare_options("lockstep")  # fail now, not in the middle of a run
    spec.compare_options("live")
    return spec


def find_fixtures(root: Path) -> list[FixtureSpec]:
    """Every fixture under ``root`` (directories holding a ``spec.yaml``), by name."""
    return [load_spec(p.parent) for p in sorted(root.glob(f"*/{SPEC_FILE}"))]
