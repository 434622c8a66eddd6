"""``-o OUT.mcap``: every command that writes a bag writes one MCAP file, as ``mcap convert``
does, and refuses in one error line what one file cannot be."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from surgery_samples import mcap_messages, rosbags_messages, run, run_here, write_mixed_bag

from bagkit.bag import BagReader


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_mixed_bag(tmp_path_factory.mktemp("in") / "mixed", 600)


@pytest.mark.parametrize("command", ["convert", "filter", "merge", "recover", "migrate"])
def test_a_mcap_output_is_one_file(mixed: Path, tmp_path: Path, command: str) -> None:
    out = tmp_path / "out.mcap"
    result = run_here(command, str(mixed), "-o", str(out))
    assert result.returncode == 0, result.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["out.mcap"]
    assert out.is_file()
    assert mcap_messages([out]) == rosbags_messages(mixed)
    with open(out, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert [m.name for m in summary.metadata_indexes] == ["rosbag2"]
    with BagReader(out) as reader:  # read back as a bag, its file named as it is
        assert [f.name for f in reader.files] == ["out.mcap"]
        assert reader.message_count == len(rosbags_messages(mixed))


def test_force_replaces_a_mcap_file(mixed: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.mcap"
    out.write_bytes(b"old")
    assert run_here("filter", str(mixed), "-o", str(out)).returncode == 2
    result = run_here("filter", str(mixed), "-o", str(out), "--force", "--topics", "/text")
    assert result.returncode == 0, result.stderr
    assert {m[0] for m in mcap_messages([out])} == {"/text"}


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["convert", "--storage", "sqlite3"], "--storage: sqlite3 writes a bag directory"),
        (["filter", "-b", "1MiB"], "--max-bag-size, --max-bag-duration: "),
        (["merge", "-d", "5"], "--max-bag-size, --max-bag-duration: "),
        (["filter", "--around", "/text: data == 'never'"], "--around writes a directory"),
    ],
)
def test_what_one_file_cannot_be_is_refused(
    mixed: Path, tmp_path: Path, args: list[str], says: str
) -> None:
    command, *options = args
    result = run(command, str(mixed), "-o", str(tmp_path / "out.mcap"), *options)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("error: ") and len(result.stderr.splitlines()) == 1
    assert says in result.stderr
    assert list(tmp_path.iterdir()) == []
