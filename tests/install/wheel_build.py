"""Build a wheel of this checkout as a user's ``pip install`` would, from a copy of its sources
(so that the build's files stay out of the checkout and two runs never share them)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

UNBUILT = shutil.ignore_patterns("build", "*.egg-info", "__pycache__", "*.so", "pyproject.toml.*")


def uv() -> str | None:
    """The uv of this environment (a dev dependency), if there is one."""
    return shutil.which("uv", path=str(Path(sys.executable).parent))


def build_wheel(project: Path, members: Sequence[str], out: Path) -> Path:
    """The wheel of ``project`` (its ``members`` copied, then built with uv, else pip)."""
    source = out / f"{project.name}-source"
    source.mkdir(parents=True)
    for name in members:
        if (project / name).is_dir():
            shutil.copytree(project / name, source / name, ignore=UNBUILT)
        else:
            shutil.copy2(project / name, source / name)
    tool = uv()
    command = (
        [
            tool,
            "build",
            "--quiet",
            "--wheel",
            "--python",
            sys.executable,
            "-o",
            str(out),
            str(source),
        ]
        if tool
        else [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--quiet",
            "--no-deps",
            "-w",
            str(out),
            str(source),
        ]
    )
    built = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
    assert built.returncode == 0, built.stderr
    (wheel,) = out.glob("*.whl")
    return wheel
