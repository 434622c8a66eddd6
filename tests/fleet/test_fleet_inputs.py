"""Many-bag inputs: directories searched for bags, globs, listings; each bag once, in order."""

from __future__ import annotations

from pathlib import Path

import pytest

from bagkit.fleet import NoBagsError, expand_bags
from bagkit.fleet.inputs import bag_paths


def _bag(path: Path) -> Path:
    path.mkdir(parents=True)
    (path / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (path / f"{path.name}_0.mcap").write_bytes(b"")
    return path


def test_roots_globs_and_listings(tmp_path: Path) -> None:
    a = _bag(tmp_path / "fleet" / "a")
    b = _bag(tmp_path / "fleet" / "day2" / "b")
    loose = tmp_path / "fleet" / "loose.mcap"
    loose.write_bytes(b"")
    (tmp_path / "fleet" / "notes.md").write_text("not a bag")
    assert expand_bags([tmp_path / "fleet"]) == [a, b, loose]  # path order: day2/b < loose
    assert expand_bags([a]) == [a]  # a bag directory is not searched for bags inside it
    assert expand_bags([str(tmp_path / "fleet" / "**" / "b")]) == [b]
    listing = tmp_path / "bags.txt"
    listing.write_text(f"# flights\n{b}\n\nfleet/a  # relative to the listing\n{b}\n")
    assert expand_bags([listing]) == [b, a]
    assert expand_bags([listing, tmp_path / "fleet"]) == [b, a, loose]


def test_nothing_to_read_is_an_error(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(NoBagsError, match="no bag in"):
        expand_bags([tmp_path / "empty", str(tmp_path / "*.mcap")])


def test_a_missing_path_is_one_error_as_in_every_command(tmp_path: Path) -> None:
    with pytest.raises(NoBagsError, match=r"gone: no such file or directory$"):
        expand_bags([tmp_path / "gone"])


ROOTS = [".", "./", "fleet", "fleet/", "./fleet", "fleet//day2", "fleet/*"]


@pytest.mark.parametrize("root", ROOTS)
def test_bag_paths_are_the_strings_of_expand_bags(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, root: str
) -> None:
    """The catalogue stores bag_paths: the same text as str() of expand_bags' Paths."""
    for bag in ["fleet/a", "fleet/day2/b", "fleet/day2/c", "fleet/.hidden/z"]:
        (tmp_path / bag).mkdir(parents=True)
        (tmp_path / bag / "metadata.yaml").write_text("x")
    (tmp_path / "fleet" / "loose.mcap").write_bytes(b"x")
    monkeypatch.chdir(tmp_path)
    found = bag_paths([root])
    assert found == [str(path) for path in expand_bags([root])]
    assert found == [str(Path(path)) for path in found] and "fleet/day2/b" in found
    assert bag_paths([tmp_path / root]) == [str(p) for p in expand_bags([tmp_path / root])]


def test_file_compressed_bags_without_metadata_are_bags(tmp_path: Path) -> None:
    # rosbag2's file compression names its files .mcap.zstd / .db3.zstd: a directory of them
    # without metadata.yaml is a bag, a loose one too, as the reader opens them.
    split = tmp_path / "fleet" / "split"
    split.mkdir(parents=True)
    for name in ("split_0.db3.zstd", "split_1.db3.zstd"):
        (split / name).write_bytes(b"x")
    loose = tmp_path / "fleet" / "loose.mcap.zstd"
    loose.write_bytes(b"x")
    (tmp_path / "fleet" / "notes.zstd").write_bytes(b"not a bag")
    assert expand_bags([tmp_path / "fleet"]) == [loose, split]
    assert bag_paths([tmp_path / "fleet"]) == [str(loose), str(split)]
