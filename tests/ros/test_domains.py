"""bagkit.ros.domains: domains held by one process, passed over while bound or held elsewhere."""

from __future__ import annotations

import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from bagkit.ros import domains
from bagkit.ros.errors import RosError


@pytest.fixture
def locks(monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The machine's lock directory (other test processes hold theirs there too); the locks
    the test takes are released after it."""
    held: list[object] = []
    monkeypatch.setattr(domains, "_held", held)
    yield domains._LOCKS
    for lock in held:
        lock.close()  # type: ignore[attr-defined]


@pytest.fixture
def two_domains(locks: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """Domains 200 and 201 only, locked in ``tmp_path`` (returned), away from other tests'."""
    monkeypatch.setattr(domains, "_LOCKS", tmp_path)
    monkeypatch.setattr(domains, "FIRST", 200)
    monkeypatch.setattr(domains, "LAST", 201)
    return tmp_path


def _seed_for(domain: int, count: int = 1) -> int:
    """The seed whose search starts at ``domain``."""
    return (domain - domains.FIRST) // count


def test_a_held_domain_is_not_given_again(locks: Path) -> None:
    first = domains.reserve(1, _seed_for(150))
    second = domains.reserve(1, _seed_for(first))
    assert domains.FIRST <= first <= domains.LAST and domains.FIRST <= second <= domains.LAST
    assert second != first


def test_a_pair_is_two_held_domains(locks: Path) -> None:
    first = domains.reserve(2, _seed_for(160, 2))
    single = domains.reserve(1, _seed_for(first))
    assert single not in (first, first + 1)


def test_a_domain_whose_ports_are_bound_is_passed_over(locks: Path) -> None:
    domain = domains.reserve(1, _seed_for(170))
    domains._held.pop().close()  # free it again, then bind one of its ports
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as bound:
        try:
            bound.bind(("127.0.0.1", domains.PORT_BASE + domains.DOMAIN_GAIN * domain + 201))
        except OSError as exc:
            pytest.skip(f"port of domain {domain} in use: {exc}")
        assert domains.reserve(1, _seed_for(domain)) != domain
    assert domains.reserve(1, _seed_for(domain)) == domain


def test_another_process_holding_a_domain_keeps_it(locks: Path) -> None:
    script = (
        "import sys; from pathlib import Path; from bagkit.ros import domains; "
        f"domains._LOCKS = Path({str(locks)!r}); "
        f"print(domains.reserve(1, {_seed_for(180)}), flush=True); sys.stdin.read()"
    )
    holder = subprocess.Popen(
        [sys.executable, "-c", script],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None
        held = int(holder.stdout.readline())
        assert domains.reserve(1, _seed_for(held)) != held
    finally:
        holder.kill()
        holder.wait()
    # Its lock went with it.
    assert domains.reserve(1, _seed_for(held)) == held


def test_no_free_domain_is_an_error_that_says_what_to_do(two_domains: Path) -> None:
    domains.reserve(2, 0)
    with pytest.raises(RosError, match="no 1 free ROS domains in 200 - 201: set ROS_DOMAIN_ID"):
        domains.reserve(1, 0)


def test_a_lock_directory_that_cannot_be_made_is_an_error_that_says_what_to_do(
    locks: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_bytes(b"")
    monkeypatch.setattr(domains, "_LOCKS", blocker / "locks")
    with pytest.raises(RosError, match=r"cannot hold ROS domains in .*: set ROS_DOMAIN_ID$"):
        domains.reserve(1, 0)


def test_a_lock_file_this_process_cannot_open_is_another_users_domain(two_domains: Path) -> None:
    (two_domains / "200.lock").mkdir()  # opening it for writing fails, as another user's file
    assert domains.reserve(1, 0) == 201
