"""``bagkit check --html``: one plot per broken assertion, each span where it broke shaded,
rendered by a real headless Chromium with no network."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from chromium import dump_dom

FIXTURES = Path(__file__).parents[2] / "fixtures"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
SPEC = """\
topics:
  /imu/data:
    max_gap: 300ms
    never: ["unchanged(linear_acceleration) for 1s"]
  /gps/fix:
    never: [isnan(*)]
  /temperature:
    values:
      temperature: {max: 50}
  /alerts:
    never: ["status[*].level >= 2"]
"""
SHADE = re.compile(r"<path[^>]*fill: rgb\(214, 39, 40\)[^>]*>")


def test_a_plot_per_failure_with_its_spans_shaded(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    page = tmp_path / "report" / "check.html"
    done = subprocess.run(
        [
            BAGKIT,
            "check",
            FIXTURES / "faults" / "golden",
            "--spec",
            spec,
            "--html",
            page,
            "--format",
            "json",
        ],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1, done.stderr
    (report,) = json.loads(done.stdout)
    failed = [a for a in report["assertions"] if not a["passed"]]
    assert len(failed) == 4  # the IMU frozen, the GPS's NaN, the temperature spike, alerts
    source = page.read_text()
    assert not re.findall(r"<script[^>]+src=|<link[^>]+href=", source)  # nothing fetched
    # Each shaded rectangle where the JSON report says the assertion broke (bag seconds).
    shapes = [json.loads(m) for m in re.findall(r'"shapes":(\[.*?\])', source)]
    assert len(shapes) == len(failed)
    for assertion, rects in zip(failed, shapes, strict=True):
        episodes = assertion["episodes"]
        assert len(rects) == len(episodes)
        for rect, episode in zip(rects, episodes, strict=True):
            assert rect["x0"] <= episode["start_s"] <= episode["end_s"] <= rect["x1"]
            assert rect["x1"] - rect["x0"] < episode["end_s"] - episode["start_s"] + 0.2
    dom = dump_dom(page)
    assert dom.count('class="plot-container plotly"') == len(failed)
    assert len(SHADE.findall(dom)) == sum(len(a["episodes"]) for a in failed)
    assert dom.count('class="trace scatter') >= len(failed)
    assert "bagkit filter" in dom and "time since bag start [s]" in dom
