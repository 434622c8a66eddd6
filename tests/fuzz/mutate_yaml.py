"""Mutations of a bag's metadata.yaml: hostile values at any place of its tree, and hostile text
(deep nesting, alias bombs, bytes that are not UTF-8, paths out of the bag)."""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Any

import yaml

HOSTILE_VALUES: dict[str, Any] = {
    "inf": math.inf,
    "nan": math.nan,
    "text": "not a number",
    "empty": "",
    "null": None,
    "-1": -1,
    "2**64": 1 << 64,
    "true": True,
    "list": [1, "two", None],
    "mapping": {"a": {"b": 1}},
    "bytes": b"\xff\xfe",
    "deep": [[[[[[[["x"]]]]]]]],
    "float": 1.5,
    "huge-string": "x" * 100_000,
}


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every place in the tree (mapping keys and list indexes)."""
    found = [prefix]
    if isinstance(node, dict):
        for key, value in node.items():
            found += _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            found += _paths(value, (*prefix, index))
    return found


def replace_value(rng: random.Random, text: str) -> tuple[str, str]:
    """One place of the document (any depth) replaced by a hostile value: (new text, recipe)."""
    document = yaml.safe_load(text)
    place = rng.choice(_paths(document)[1:] or [()])
    label = rng.choice(sorted(HOSTILE_VALUES))
    value = HOSTILE_VALUES[label]
    if not place:
        document = value
    else:
        parent = document
        for step in place[:-1]:
            parent = parent[step]
        parent[place[-1]] = value
    recipe = f"{'.'.join(map(str, place)) or 'root'} = {label}"
    return yaml.safe_dump(document, sort_keys=False), recipe


def _alias_bomb(levels: int) -> str:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, levels)]
    root = "rosbag2_bagfile_information"
    lines.append(f"{root}: {{storage_identifier: mcap, custom_data: {{bomb: *a{levels - 1}}}}}")
    return "\n".join(lines) + "\n"


def mutate(rng: random.Random, bag: Path, outside: Path) -> str:
    """Mutate ``bag/metadata.yaml`` in place; ``outside`` is a storage file outside the bag (for
    symlinks that leave it). Returns the recipe."""
    path = bag / "metadata.yaml"
    text = path.read_text(encoding="utf-8") if path.is_file() else ""
    kind = rng.choice(
        ["value", "value", "value", "nested", "alias", "utf8", "truncate", "flip", "paths", "tag"]
    )
    if kind == "value" and text:
        new, where = replace_value(rng, text)
        recipe = f"yaml value {where}"
        path.write_text(new)
    elif kind == "nested":
        depth = rng.choice([100, 1000, 30_000])
        opener = rng.choice(["[", "{a: "])
        path.write_text("rosbag2_bagfile_information: " + opener * depth)
        recipe = f"yaml nested {opener!r} x {depth}"
    elif kind == "alias":
        levels = rng.choice([3, 10])
        path.write_text(_alias_bomb(levels))
        recipe = f"yaml alias bomb of {levels} levels"
    elif kind == "utf8":
        raw = bytearray(text.encode())
        at = rng.randrange(len(raw) + 1)
        raw[at:at] = rng.choice([b"\xff", b"\xc3", b"\xed\xa0\x80", b"\x00"])
        path.write_bytes(bytes(raw))
        recipe = f"yaml byte not UTF-8 at {at}"
    elif kind == "truncate":
        at = rng.randrange(len(text) + 1)
        path.write_text(text[:at])
        recipe = f"yaml truncated at {at}"
    elif kind == "flip":
        raw = bytearray(text.encode())
        for _ in range(rng.randint(1, 8)):
            if raw:
                raw[rng.randrange(len(raw))] ^= 1 << rng.randrange(7)
        path.write_bytes(bytes(raw))
        recipe = "yaml bits flipped"
    elif kind == "paths":
        recipe = _escape_paths(rng, bag, path, text, outside)
    else:
        tag = rng.choice(["!!python/object/apply:os.system ['true']", "!!binary AAAA", "!!set {a}"])
        path.write_text(text.replace("storage_identifier: ", f"storage_identifier: {tag} #", 1))
        recipe = f"yaml tag {tag}"
    return recipe


def _escape_paths(rng: random.Random, bag: Path, path: Path, text: str, outside: Path) -> str:
    """relative_file_paths naming files outside the bag: absolute, .., or a symlink."""
    document = yaml.safe_load(text) if text else None
    if not isinstance(document, dict):
        return "yaml paths: no document (unchanged)"
    root = document.get("rosbag2_bagfile_information", document)
    choice = rng.choice(["absolute", "dotdot", "symlink", "nul"])
    if choice == "absolute":
        listed = str(outside)
    elif choice == "dotdot":
        listed = "../" + outside.name
    elif choice == "nul":
        listed = "a\x00b.mcap"
    else:
        listed = "linked" + outside.suffix
        (bag / listed).symlink_to(outside)
    root["relative_file_paths"] = [listed]
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return f"yaml relative_file_paths = [{choice}: {listed!r}]"
