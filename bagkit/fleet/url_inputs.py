"""Bags in storage named by a URL: a bag (a prefix holding ``metadata.yaml``, or a storage
file), or a prefix of bags, expanded as :func:`bagkit.fleet.inputs.find_bags` expands a local
directory, from one listing of the prefix."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from bagkit.fleet.errors import NoBagsError
from bagkit.storage.paths import UrlPath
from bagkit.storage.transfer import objects_under
from bagkit.storage.urls import joined, path_part, scheme


def in_path_order(bags: Iterable[str]) -> list[str]:
    """The bags found under one folder or prefix in path order (docs/fleet.md): by name at
    each level, folders and files together, as ``ls -R`` shows a tree. A folder and a prefix
    holding the same bags give the same order (pure)."""
    return sorted(bags, key=lambda bag: bag.split("/"))


def url_bags(
    url: str, storage_suffixes: tuple[str, ...], bag_suffixes: tuple[str, ...]
) -> list[str]:
    """The bags ``url`` names, in path order within the prefix (:func:`in_path_order`).

    Args:
        url: a storage file, a bag's prefix, or a prefix of bags.
        storage_suffixes: a storage file's names (a prefix holding only these is one bag).
        bag_suffixes: names of files that are bags by themselves.

    Raises:
        NoBagsError: nothing at ``url``. Other StorageErrors: the store refused the listing.
    """
    if path_part(url).rstrip("/").endswith(bag_suffixes):
        return [url]  # a file (a presigned URL's query kept)
    prefix = UrlPath(url)
    if scheme(url) in ("http", "https"):
        # No listing: what fsspec lists of an HTTP URL is the links of a page, not objects.
        if prefix.is_dir():  # a bag's prefix, known by its metadata.yaml
            return [url]
        raise NoBagsError(
            f"{prefix}: no bag there (an HTTP server lists no prefixes: name each bag, by its "
            ".mcap file or the prefix holding its metadata.yaml)"
        )
    names = [o.relative_to(prefix) for o in objects_under(prefix)]
    if not names:
        if prefix.is_file() or prefix.is_dir():  # HTTP: a bag's prefix, known by metadata.yaml
            return [url]
        raise NoBagsError(f"{prefix}: no such object or prefix")
    return [
        joined(prefix.url, bag) if bag else prefix.url
        for bag in in_path_order(_bags(names, storage_suffixes, bag_suffixes))
    ]


def _bags(names: list[str], storage: tuple[str, ...], bag_files: tuple[str, ...]) -> Iterator[str]:
    """The bags among the object ``names`` (relative, ``/``-separated): as ``find_bags`` walks
    a directory ("" is the prefix itself)."""
    files: dict[str, list[str]] = {}
    subdirs: dict[str, set[str]] = {}
    for name in names:
        directory, _, base = name.rpartition("/")
        files.setdefault(directory, []).append(base)
        parts = directory.split("/") if directory else []
        for depth in range(len(parts)):
            above = "/".join(parts[:depth])
            subdirs.setdefault(above, set()).add(parts[depth])
            files.setdefault("/".join(parts[: depth + 1]), [])

    def is_bag(directory: str) -> bool:
        held = files.get(directory, [])
        if "metadata.yaml" in held:
            return True
        return not subdirs.get(directory) and any(f.endswith(storage) for f in held)

    def walk(directory: str) -> Iterator[str]:
        if is_bag(directory):
            yield directory
            return
        for sub in sorted(subdirs.get(directory, ())):
            if not sub.startswith("."):
                yield from walk(f"{directory}/{sub}" if directory else sub)
        for base in sorted(files.get(directory, [])):
            if base.endswith(bag_files):
                yield f"{directory}/{base}" if directory else base

    yield from walk("")
