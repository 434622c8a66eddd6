"""Headless Chromium (Debian's ``chromium``) for rendering pages in tests."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    # Every host name fails to resolve: a page that needs the network shows it.
    "--host-resolver-rules=MAP * ~NOTFOUND",
    # Scripts (plotly) finish drawing before the DOM is dumped or the screenshot taken.
    "--virtual-time-budget=15000",
)
TIMEOUT_S = 180


def chromium() -> str:
    """The chromium executable; skips the test where there is none (fails under CI=true)."""
    found = shutil.which("chromium")
    if found is None:
        reason = "headless Chromium not installed (apt-get install chromium; .ci/run does)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    return found


def _run(page: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    with tempfile.TemporaryDirectory(prefix="chromium-profile-") as profile:
        return subprocess.run(
            [chromium(), *FLAGS, f"--user-data-dir={profile}", *extra, page.as_uri()],
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
            check=True,
        )


def dump_dom(page: Path) -> str:
    """The DOM of ``page`` after Chromium has loaded it."""
    return _run(page, "--dump-dom").stdout


def screenshot(page: Path, png: Path, width: int = 1000, height: int = 1400) -> Path:
    """A PNG of ``page`` as Chromium renders it."""
    _run(page, f"--screenshot={png}", f"--window-size={width},{height}")
    return png
