"""Results made once per test session and shared by its pytest-xdist workers.

A golden fixture's run in one mode serves its item and its health items, which xdist sends to
different workers in most of its dist modes (``load``, ``worksteal``, ``loadgroup``, and
``each`` runs every item on every worker). The first worker that needs a result makes it while
holding an exclusive ``flock`` on a file in a directory the controller made and handed to every
worker, and leaves it there pickled; a worker that needs it meanwhile waits on the lock and
reads it. Live runs also hold a lock on their ROS domain: where workers share one (a
``ROS_DOMAIN_ID`` the user set), their live runs take turns instead of seeing each other.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import pickle
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import pytest

T = TypeVar("T")
# The workerinput key under which the controller hands its directory to the workers.
WORKER_KEY = "bagkit_golden_shared"
_MADE = pytest.StashKey[Path]()  # the controller's
_SHARED = pytest.StashKey[Path]()  # a worker's
# This process's results by key: ``(True, value)`` or ``(False, exception)``.
_RESULTS = pytest.StashKey[dict[str, tuple[bool, Any]]]()


def hand_to_worker(config: pytest.Config, workerinput: dict[str, Any]) -> None:
    """On the controller: the session's shared directory (made on the first worker's start,
    removed at the end) into a worker's ``workerinput``."""
    if _MADE not in config.stash:
        directory = Path(tempfile.mkdtemp(prefix="bagkit-golden-"))
        config.stash[_MADE] = directory
        config.add_cleanup(lambda: shutil.rmtree(directory, ignore_errors=True))
    workerinput[WORKER_KEY] = str(config.stash[_MADE])


def check_worker(config: pytest.Config) -> None:
    """On an xdist worker: the controller's shared directory is here, or a usage error (a
    worker on another machine, or a controller without the plugin, would run each fixture
    again instead of sharing its run)."""
    workerinput = getattr(config, "workerinput", None)
    if workerinput is None:
        return
    given = workerinput.get(WORKER_KEY)
    if given is None or not Path(given).is_dir():
        where = "none was handed over" if given is None else f"{given} is not on this machine"
        raise pytest.UsageError(
            "golden fixtures under pytest-xdist share each run through the controller's "
            f"directory, and {where}: run the workers on the controller's machine "
            "(-n, not --tx ssh=...) with the bagkit plugin loaded in both"
        )
    config.stash[_SHARED] = Path(given)


def once(config: pytest.Config, key: str, make: Callable[[], T]) -> T:
    """``make()``'s result (or its exception, raised again) made once in this session, whatever
    worker asks first; ``key`` names it (a fixture's directory and mode)."""
    results = config.stash.setdefault(_RESULTS, {})
    if key not in results:
        directory = config.stash.get(_SHARED, None)
        if directory is None:
            results[key] = _outcome(make)
        else:
            results[key] = _shared(directory / hashlib.sha256(key.encode()).hexdigest(), make)
    made, found = results[key]
    if not made:
        raise found
    return found


def _outcome(make: Callable[[], T]) -> tuple[bool, T | Exception]:
    try:
        return True, make()
    except Exception as exc:
        return False, exc


def _shared(stem: Path, make: Callable[[], T]) -> tuple[bool, Any]:
    """The outcome stored at ``stem``, or made and stored there, under ``stem``'s lock."""
    stored = stem.with_suffix(".pickle")
    with _locked(stem.with_suffix(".lock")):
        if stored.exists():
            return pickle.loads(stored.read_bytes())
        outcome = _outcome(make)
        partial = stem.with_suffix(".partial")
        partial.write_bytes(pickle.dumps(_portable(outcome)))
        os.replace(partial, stored)
        return outcome


def _portable(outcome: tuple[bool, Any]) -> tuple[bool, Any]:
    """An exception another worker can unpickle: itself, or its type's name and message (an
    exception whose ``__init__`` takes other arguments than its ``args`` cannot be rebuilt)."""
    made, found = outcome
    if made:
        return outcome
    try:
        pickle.loads(pickle.dumps(found))
    except Exception:
        return False, RuntimeError(f"{type(found).__name__}: {found}")
    return outcome


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    with path.open("wb") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, or the process dies
        yield


@contextmanager
def domain_turn(config: pytest.Config) -> Iterator[None]:
    """Hold this session's lock on the current ``ROS_DOMAIN_ID`` (no-op outside xdist)."""
    directory = config.stash.get(_SHARED, None)
    if directory is None:
        yield
        return
    with _locked(directory / f"domain-{os.environ.get('ROS_DOMAIN_ID', '0')}.lock"):
        yield
