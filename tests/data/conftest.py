"""Sample bags shared by the data tests (written once per session)."""

from __future__ import annotations

from pathlib import Path

import pytest
from samples import write_sample_bag


@pytest.fixture(scope="session")
def sample_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_sample_bag(tmp_path_factory.mktemp("data") / "sample")
