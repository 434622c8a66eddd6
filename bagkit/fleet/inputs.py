"""Many-bag inputs: bag directories, bare ``.mcap``/``.db3`` files (``.zstd``-compressed too),
ROS 1 ``.bag`` files, globs, roots searched for bags, text files listing one path a line, and
URLs of bags or of prefixes searched for bags (:mod:`bagkit.fleet.url_inputs`).

The result is a list of bags in a stable order, each bag once: the order given; within a
directory or a prefix, path order (:func:`~bagkit.fleet.url_inputs.in_path_order`); a glob's
matches sorted.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

from bagkit.bag import storage_files
from bagkit.bag.storage_files import bag_path
from bagkit.fleet.errors import NoBagsError
from bagkit.fleet.url_inputs import in_path_order, url_bags
from bagkit.storage.paths import UrlPath
from bagkit.storage.urls import is_url

# The reader's storage files, rosbag2's file-compressed ones too (.mcap.zstd, .db3.zstd).
STORAGE_SUFFIXES = storage_files.STORAGE_SUFFIXES + storage_files.COMPRESSED_STORAGE_SUFFIXES
# A file that is a whole bag by itself (ROS 1 bags: several in a directory are several bags).
BAG_FILE_SUFFIXES = (*STORAGE_SUFFIXES, ".bag")
LISTING_SUFFIXES = (".txt", ".list", ".lst")
# A listing longer than this is not a list of bag paths (bounded memory on a wrong file).
MAX_LISTING_BYTES = 64 << 20


def is_bag_directory(path: str | Path) -> bool:
    """A rosbag2 bag directory: it holds ``metadata.yaml``, or storage files and no directory.

    (A directory of loose ``.mcap`` files beside sub-directories is a root of several bags.)
    In storage: a prefix holding ``metadata.yaml``.
    """
    if is_url(path):
        return (UrlPath(str(getattr(path, "url", path))) / "metadata.yaml").is_file()
    if os.path.isfile(os.path.join(path, "metadata.yaml")):
        return True
    storage = False
    try:
        with os.scandir(path) as entries:
            for entry in entries:
                if entry.is_dir():
                    return False
                storage = storage or (entry.name.endswith(STORAGE_SUFFIXES) and entry.is_file())
    except OSError:
        return False
    return storage


def find_bags(root: str) -> Iterator[str]:
    """Bags under ``root``: bag directories (not searched further) and loose storage files.

    Strings, not Paths: a catalogue update of 1,000 unchanged bags is mostly this walk
    (benchmarks/README.md, "fleet"). Joined as ``Path`` would join them (``root`` as
    ``str(Path(...))`` gives it).
    """
    if is_bag_directory(root):
        yield root
        return
    for directory, subdirs, files in os.walk(root, followlinks=False):
        subdirs.sort()
        bags = [d for d in subdirs if is_bag_directory(os.path.join(directory, d))]
        for name in bags:
            yield _joined(directory, name)
        subdirs[:] = [d for d in subdirs if d not in bags and not d.startswith(".")]
        for name in sorted(files):
            if name.endswith(BAG_FILE_SUFFIXES):
                yield _joined(directory, name)


def _joined(directory: str, name: str) -> str:
    """``str(Path(directory, name))`` for what os.walk gives: ``./a`` is ``a``."""
    path = os.path.join(directory, name)
    return path[2:] if path.startswith("./") else path


def _listing(path: Path) -> list[Path]:
    """The paths listed in a text file, one a line; ``#`` starts a comment; relative to it."""
    if path.stat().st_size > MAX_LISTING_BYTES:
        raise NoBagsError(f"{path}: a listing of bag paths larger than {MAX_LISTING_BYTES} bytes")
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    entries = [line.split("#", 1)[0].strip() for line in lines]
    return [path.parent / entry for entry in entries if entry]


def _expand(item: Path, *, listed: bool = False) -> Iterator[str]:
    text = str(item)
    if glob.has_magic(text):
        for match in sorted(glob.glob(text, recursive=True)):
            yield from _expand(Path(match), listed=listed)
    elif item.is_dir():
        yield from in_path_order(find_bags(text))
    elif item.suffix in LISTING_SUFFIXES and item.is_file() and not listed:
        # Listings are not followed from listings: no cycle to guard against.
        for entry in _listing(item):
            yield from _expand(entry, listed=True)
    else:
        # A storage file, or a path that does not exist: reading it reports what is wrong.
        yield text


def bag_paths(items: Iterable[str | Path]) -> list[str]:
    """:func:`expand_bags` as strings (``str`` of each Path), without making the Paths.

    Raises:
        NoBagsError: as :func:`expand_bags`.
    """
    items = list(items)
    seen: dict[str, str] = {}
    for item in items:
        if isinstance(item, UrlPath) or is_url(item):
            for bag in url_bags(
                str(getattr(item, "url", item)), STORAGE_SUFFIXES, BAG_FILE_SUFFIXES
            ):
                seen.setdefault(bag, bag)
            continue
        path = Path(item)
        if not glob.has_magic(str(item)) and not os.path.lexists(path):
            raise NoBagsError(f"{item}: no such file or directory")
        for bag in _expand(path):
            seen.setdefault(os.path.normpath(bag), bag)
    if not seen:
        raise NoBagsError(f"no bag in {', '.join(str(i) for i in items) or 'the inputs'}")
    return list(seen.values())


def expand_bags(items: Iterable[str | Path]) -> list[Path]:
    """Every bag named by ``items``, each once, in the order given.

    Raises:
        NoBagsError: nothing names a bag, or a path given (not a glob) does not exist: the
            same error every command gives for a missing path.
    """
    return [bag_path(bag) for bag in bag_paths(items)]
