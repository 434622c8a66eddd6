"""A golden recorded with an older definition of an input's type: the lockstep check fails with
the drift (not value diffs), ``golden update`` refuses, ``golden migrate`` makes it pass.

The fixture is a copy of fixtures/nominal whose /temperature was written the way an older
sensor_msgs had Temperature (without ``variance``): ``bagkit migrate --to-package`` of a
source directory holding that Temperature.msg, so the golden's stored definition and its
payloads are the old layout's.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bagkit.bag import BagReader, message_definition

REPO = Path(__file__).resolve().parents[2]
BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _bagkit(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, *args], cwd=cwd, capture_output=True, text=True, timeout=300, check=False
    )


@pytest.fixture
def drifted_fixture(tmp_path: Path) -> Path:
    """fixtures/nominal with /temperature in the layout without ``variance``."""
    shutil.copytree(REPO / "fixtures" / "nominal", tmp_path / "fixtures" / "nominal")
    fixture = tmp_path / "fixtures" / "nominal"
    old_package = tmp_path / "old_sensor_msgs"
    (old_package / "msg").mkdir(parents=True)
    (old_package / "package.xml").write_text("<package><name>sensor_msgs</name></package>\n")
    text = message_definition("sensor_msgs/msg/Temperature").split("\n" + "=" * 80, 1)[0]
    kept = [line for line in text.splitlines() if not line.startswith("float64 variance")]
    (old_package / "msg" / "Temperature.msg").write_text("\n".join(kept) + "\n")
    old = tmp_path / "old_golden"
    made = _bagkit("migrate", str(fixture / "golden"), "-o", str(old), "--to-package",
                   str(old_package), "--allow-drop", cwd=tmp_path)  # fmt: skip
    assert made.returncode == 0, made.stderr
    shutil.rmtree(fixture / "golden")
    old.rename(fixture / "golden")
    return fixture


def test_check_fails_with_the_drift_and_migrate_makes_it_pass(
    drifted_fixture: Path, tmp_path: Path
) -> None:
    fixture = drifted_fixture
    checked = _bagkit("golden", "check", str(fixture), cwd=tmp_path)
    assert checked.returncode == 1, checked.stdout + checked.stderr
    assert "nominal (lockstep): FAIL" in checked.stdout
    assert (  # a line past 80 columns goes on, indented, on the next
        "/temperature (sensor_msgs/msg/Temperature): the golden's definition differs from the "
        "installed one: added: variance (float64)" in " ".join(checked.stdout.split())
    )
    assert "max |err|" not in checked.stdout  # no value diffs
    report = json.loads(
        (tmp_path / "golden_failures" / "nominal-lockstep" / "report.json").read_text()
    )
    assert report["drift"][0]["topic"] == "/temperature"
    assert report["drift"][0]["changes"] == ["added: variance (float64)"]

    plugin = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--golden-root", "fixtures"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert plugin.returncode == 1, plugin.stdout + plugin.stderr
    assert "the golden's definition differs from the installed one: added: variance" in (
        " ".join(plugin.stdout.split())
    )
    assert "1 failed" in plugin.stdout

    refused = _bagkit("golden", "update", str(fixture), cwd=tmp_path)
    assert refused.returncode == 1
    assert refused.stderr.startswith("error: nominal: the golden's definitions drifted")
    assert "added: variance (float64)" in refused.stderr

    migrated = _bagkit("golden", "migrate", str(fixture), cwd=tmp_path)
    assert migrated.returncode == 0, migrated.stdout + migrated.stderr
    assert "nominal: /temperature migrated" in migrated.stdout
    assert "nominal (lockstep): pass" in migrated.stdout
    with BagReader(fixture / "golden") as reader:
        assert reader.definitions["sensor_msgs/msg/Temperature"] == message_definition(
            "sensor_msgs/msg/Temperature"
        )
    assert not [p for p in fixture.iterdir() if p.name.startswith(".")]
    again = _bagkit("golden", "check", str(fixture), cwd=tmp_path)
    assert again.returncode == 0, again.stdout
