"""YAML from files we did not write, loaded with limits on size, nesting, nodes and aliases.

libyaml's composer recurses once per nesting level in C (30,000 ``[`` end the process with
SIGSEGV) and aliases let a kilobyte describe billions of nodes (any code that walks the result
then hangs). So the document's events are scanned first, streaming and without recursion, and
only a document within the limits is loaded. rosbag2 never writes aliases: they are refused.
"""

from __future__ import annotations

from typing import Any

import yaml

MAX_YAML_BYTES = 8 * 1024 * 1024
MAX_YAML_DEPTH = 64
# Loading costs about 350 bytes of memory per node: 100,000 nodes is ~35 MiB and enough for a
# metadata.yaml listing thousands of topics and split files.
MAX_YAML_NODES = 100_000

_OPENING = (yaml.MappingStartEvent, yaml.SequenceStartEvent)
_CLOSING = (yaml.MappingEndEvent, yaml.SequenceEndEvent)
_NODES = (yaml.ScalarEvent, *_OPENING)


class YamlLimitError(yaml.YAMLError):
    """A document beyond the limits (size, depth, node count) or with an alias."""


def check_limits(
    text: str,
    *,
    max_bytes: int = MAX_YAML_BYTES,
    max_depth: int = MAX_YAML_DEPTH,
    max_nodes: int = MAX_YAML_NODES,
) -> None:
    """Raise YamlLimitError when ``text`` breaks a limit, yaml.YAMLError when it is not YAML."""
    if len(text) > max_bytes:
        raise YamlLimitError(f"larger than {max_bytes} bytes")
    depth = nodes = 0
    for event in yaml.parse(text, Loader=yaml.CSafeLoader):
        if isinstance(event, yaml.AliasEvent):
            raise YamlLimitError(f"alias *{event.anchor} (aliases are not accepted)")
        if isinstance(event, _NODES):
            nodes += 1
            if nodes > max_nodes:
                raise YamlLimitError(f"more than {max_nodes} nodes")
        if isinstance(event, _OPENING):
            depth += 1
            if depth > max_depth:
                raise YamlLimitError(f"nested deeper than {max_depth} levels")
        elif isinstance(event, _CLOSING):
            depth -= 1


def load(text: str, **limits: int) -> Any:
    """Load one YAML document (safe tags only) after :func:`check_limits`.

    Raises:
        yaml.YAMLError: not YAML, unsafe tags, or YamlLimitError.
    """
    check_limits(text, **limits)
    try:
        return yaml.load(text, Loader=yaml.CSafeLoader)
    except (ValueError, TypeError, AttributeError, OverflowError) as exc:
        # Scalars the safe constructor fails on: 2024-99-99, 5,000-digit integers, !!int abc.
        raise yaml.YAMLError(f"unreadable value ({exc})") from exc
