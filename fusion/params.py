"""Node parameters: defaults from ``fusion/config/params.yaml``, typed access for the cores."""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Iterator, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from bagkit.words import counted
from fusion.errors import ConfigError

PARAMS_FILE = Path(str(resources.files("fusion") / "config" / "params.yaml"))


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, object]:
    """Flatten nested mappings into dotted keys, as ROS 2 does with parameter files."""
    flat: dict[str, object] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat


def load_parameter_file(path: Path, node_name: str, *, wildcard: bool = True) -> dict[str, object]:
    """Return the flattened ``ros__parameters`` of ``node_name`` (and ``/**``) in ``path``.

    ``wildcard=False`` leaves the ``/**`` section out.

    Raises:
        ConfigError: the file is missing or not a ROS 2 parameter file.
    """
    try:
        # libyaml's loader: the packaged file is read for every processor a lockstep run creates.
        document = yaml.load(path.read_text(), Loader=yaml.CSafeLoader)
    except OSError as exc:
        raise ConfigError(f"cannot read parameter file {path}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        where = ""
        mark = getattr(exc, "problem_mark", None)
        if mark is not None:
            where = f" at line {mark.line + 1}, column {mark.column + 1}"
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{path} is not valid YAML: {problem}{where}") from exc
    if not isinstance(document, Mapping):
        raise ConfigError(f"{path} is not a ROS 2 parameter file (expected a mapping)")
    params: dict[str, object] = {}
    sections = ("/**", node_name, f"/{node_name}") if wildcard else (node_name, f"/{node_name}")
    for key in sections:
        section = document.get(key)
        if section is None:
            continue
        if not isinstance(section, Mapping) or "ros__parameters" not in section:
            raise ConfigError(f"{path}: section {key!r} has no 'ros__parameters'")
        params.update(flatten(section["ros__parameters"] or {}))
    return params


def default_parameters(node_name: str) -> dict[str, object]:
    """The packaged defaults of ``node_name``, flattened to dotted names (a fresh copy)."""
    return copy.deepcopy(_packaged_defaults(node_name))


@functools.cache
def _packaged_defaults(node_name: str) -> dict[str, object]:
    return load_parameter_file(PARAMS_FILE, node_name)


class Params(Mapping[str, object]):
    """Flattened parameters (defaults overlaid by overrides) with typed, checked getters."""

    def __init__(self, node_name: str, overrides: Mapping[str, object] | None = None) -> None:
        self.node_name = node_name
        self._values = default_parameters(node_name)
        unknown = sorted(set(overrides or {}) - set(self._values) - {"use_sim_time"})
        if unknown:
            unknowns = counted(len(unknown), "unknown parameter")
            raise ConfigError(f"{node_name}: {unknowns}: {', '.join(unknown)}")
        self._values.update(overrides or {})

    def __getitem__(self, key: str) -> object:
        try:
            return self._values[key]
        except KeyError:
            raise ConfigError(f"{self.node_name}: missing parameter {key!r}") from None

    def __contains__(self, key: object) -> bool:
        return key in self._values

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def number(self, key: str, *, positive: bool = False, non_negative: bool = False) -> float:
        """The parameter as a finite float (ints are accepted)."""
        value = self[key]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{self.node_name}: {key} must be a number, got {value!r}")
        result = float(value)
        if not math.isfinite(result):
            raise ConfigError(f"{self.node_name}: {key} must be finite, got {value!r}")
        if positive and result <= 0:
            raise ConfigError(f"{self.node_name}: {key} must be > 0, got {value!r}")
        if non_negative and result < 0:
            raise ConfigError(f"{self.node_name}: {key} must be >= 0, got {value!r}")
        return result

    def integer(self, key: str, *, minimum: int | None = None) -> int:
        """The parameter as an int."""
        value = self[key]
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{self.node_name}: {key} must be an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise ConfigError(f"{self.node_name}: {key} must be >= {minimum}, got {value}")
        return value

    def flag(self, key: str) -> bool:
        """The parameter as a bool."""
        value = self[key]
        if not isinstance(value, bool):
            raise ConfigError(f"{self.node_name}: {key} must be true or false, got {value!r}")
        return value

    def text(self, key: str) -> str:
        """The parameter as a string."""
        value = self[key]
        if not isinstance(value, str):
            raise ConfigError(f"{self.node_name}: {key} must be a string, got {value!r}")
        return value

    def interval(self, key: str) -> tuple[float, float]:
        """The parameter as a ``[low, high]`` pair with low <= high."""
        value = self[key]
        if (
            not isinstance(value, list | tuple)
            or len(value) != 2
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
            or value[0] > value[1]
        ):
            raise ConfigError(f"{self.node_name}: {key} must be [low, high], got {value!r}")
        return float(value[0]), float(value[1])
