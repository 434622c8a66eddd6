"""``--dist loadgroup`` that keeps a golden fixture's run on one worker: its item and its health
items go together, so that the worker that makes the run (once either way: ``shared``) is the
one that needs it and no other waits for it.

Grouped by node id, not by an ``xdist_group`` mark: xdist 3.8 sends a mark's group to the
scheduler in the node id, and pytest 9.2 no longer lets it change one (pytest-xdist#1386).
Imports pytest-xdist: only for a session that runs with it.
"""

from __future__ import annotations

from xdist.scheduler import LoadGroupScheduling

from bagkit.pytest_plugin import SPEC_FILE


def golden_run(nodeid: str) -> str | None:
    """The run a golden fixture's item uses (``fixtures/faults/spec.yaml::live``) for its own
    (``::live``) and its health items (``::live-health[...]``), and the golden's health check
    (``::golden``) for its items; None for any other item."""
    path, sep, name = nodeid.partition(f"{SPEC_FILE}::")
    if not sep or (path and not path.endswith("/")):
        return None
    return f"{path}{SPEC_FILE}::{name.split('-health[', 1)[0]}"


class GoldenRunScheduling(LoadGroupScheduling):
    """xdist's loadgroup scheduling, a golden fixture's run (``golden_run``) one group."""

    def _split_scope(self, nodeid: str) -> str:
        return golden_run(nodeid) or str(super()._split_scope(nodeid))
