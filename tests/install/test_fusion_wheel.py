"""``bagkit-fusion`` (fusion/pyproject.toml): its wheel holds every module of fusion and its
parameter file, and the ``fusion`` command; nothing of bagkit."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
from wheel_build import build_wheel

pytestmark = pytest.mark.install

FUSION = Path(__file__).resolve().parents[2] / "fusion"


def test_the_fusion_wheel_holds_fusion_whole(tmp_path: Path) -> None:
    members = [p.name for p in FUSION.iterdir() if not p.name.endswith(("build", ".egg-info"))]
    wheel = build_wheel(FUSION, members, tmp_path)
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
        entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
        scripts = archive.read(entry_points).decode()
    sources = {f"fusion/{p.relative_to(FUSION)}" for p in FUSION.rglob("*.py")}
    assert sources <= names, sorted(sources - names)
    assert "fusion/config/params.yaml" in names
    assert {n.split("/")[0] for n in names} == {"fusion", entry_points.split("/")[0]}
    assert "fusion = fusion.cli:main" in scripts
