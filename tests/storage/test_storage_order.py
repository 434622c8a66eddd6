"""The bags under a local folder and under the same objects in storage (moto's S3 server on
loopback) come in one order, documented in docs/fleet.md: path order, by name at each level,
folders and files together (what ``sorted`` gives on the paths' components)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process

from bagkit.bag import BagWriter, TopicInfo
from bagkit.fleet.inputs import bag_paths
from tests.storage.conftest import Store

# Bag directories (metadata.yaml), folders of bags, loose files, at several depths; names
# chosen so that a walk listing sub-folders before files, or bags before folders, differs.
DIRECTORIES = ["b_bag", "a_dir/x_bag", "a_dir/deeper/w_bag", ".hidden/z_bag"]
FILES = ["c.mcap", "a.mcap", "a_dir/y.mcap", "a_dir-1.mcap"]


def _tree(root: Path) -> list[str]:
    """Write the bags under ``root``; return those a search finds (relative, any order)."""
    for i, name in enumerate(DIRECTORIES):
        with BagWriter(root / name) as bag:
            bag.add_topic(TopicInfo("/n", "std_msgs/msg/UInt8"), definition="uint8 data\n")
            bag.write("/n", b"\x00\x01\x00\x00" + bytes([i]), log_time=10**18 + i)
    for name in FILES:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(root / "b_bag" / "b_bag_0.mcap", root / name)
    return [name for name in DIRECTORIES + FILES if not name.startswith(".")]


@pytest.fixture(scope="module")
def tree(
    tmp_path_factory: pytest.TempPathFactory, moto_store: Store
) -> tuple[Path, str, list[str]]:
    """(the local root, the same objects' prefix URL, the bags in path order)."""
    root = tmp_path_factory.mktemp("order") / "tree"
    found = _tree(root)
    moto_store.put(root, "order/tree")
    return root, f"{moto_store.base}/order/tree", sorted(found, key=lambda n: n.split("/"))


def _relative(paths: list[str], base: str) -> list[str]:
    return [path.removeprefix(f"{base}/") for path in paths]


def test_a_folder_and_a_prefix_expand_in_path_order(tree: tuple[Path, str, list[str]]) -> None:
    root, url, expected = tree
    assert _relative(bag_paths([root]), str(root)) == expected
    assert _relative(bag_paths([url]), url) == expected


def test_fleet_results_and_info_are_in_that_order(tree: tuple[Path, str, list[str]]) -> None:
    root, url, expected = tree
    for base in (str(root), url):
        summary = bagkit_in_process(
            ["stats", "summary", base, "--format", "json", "--workers", "0"]
        )
        assert summary.returncode == 0, summary.stderr
        assert _relative(json.loads(summary.stdout)["bags"], base) == expected
        info = bagkit_in_process(["info", base, "--format", "json"])
        assert info.returncode == 0, info.stderr
        shown = [bag["path"] for bag in json.loads(info.stdout)["bags"]]
        assert _relative(shown, base) == expected
