"""``bagkit plot``: PNG of the expected size and not blank; the HTML page rendered by headless
Chromium with no network, one trace per requested field; series values from the bag."""

from __future__ import annotations

import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
from bagkit_runs import bagkit_in_process
from chromium import dump_dom, screenshot
from matplotlib.image import imread

import bagkit
from bagkit.data.plot_png import Layout
from bagkit.data.series import decimate, load_series

REPO = Path(__file__).resolve().parents[2]
NOMINAL = REPO / "fixtures" / "nominal" / "golden"
FAULTS = REPO / "fixtures" / "faults" / "golden"


def _plot(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit plot ARGS`` in this process (tests/bagkit_runs.py)."""
    return bagkit_in_process(["plot", *args])


def _external_resources(html: str) -> list[str]:
    """src/href attributes of the page's own tags (scripts, styles, images) that load a file."""
    found: list[str] = []

    class Tags(HTMLParser):
        def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
            found.extend(v for k, v in attrs if k in ("src", "href") and v and tag != "a")

    Tags().feed(html)
    return found


def test_png_has_the_expected_size_and_is_not_blank(tmp_path: Path) -> None:
    out = tmp_path / "p.png"
    result = _plot(
        NOMINAL,
        "/imu/data:linear_acceleration.z",
        "/temperature:temperature",
        "-o",
        out,
        "--bag",
        FAULTS,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"4 series -> {out}"
    image = imread(out)
    page = Layout("")
    height_in = page.margin_height_in + 2 * page.panel_height_in
    assert image.shape[:2] == (round(height_in * page.dpi), round(page.width_in * page.dpi))
    gray = image[..., :3].mean(axis=2)
    assert gray.std() > 0.05  # lines, text and axes on white, not one colour
    assert (gray < 0.5).mean() > 0.005


def test_html_renders_offline_with_one_trace_per_field(tmp_path: Path) -> None:
    out = tmp_path / "page.html"
    result = _plot(
        NOMINAL,
        "/imu/data:linear_acceleration.*",
        "/barometer/pressure:fluid_pressure",
        "-o",
        out,
        "--bag",
        FAULTS,
    )
    assert result.returncode == 0, result.stderr
    assert _external_resources(out.read_text()) == []
    dom = dump_dom(out)
    # 4 fields x 2 bags, drawn as SVG by plotly's JavaScript (inlined in the page).
    assert dom.count('class="trace scatter') == 8
    assert "fluid_pressure [Pa]" in dom and "linear_acceleration.z [m/s²]" in dom
    assert "time since bag start [s]" in dom
    shot = tmp_path / "shot.png"
    screenshot(out, shot, width=1200, height=1400)
    assert imread(shot)[..., :3].std() > 0.05


def test_series_are_the_bag_values_on_seconds_from_start() -> None:
    [z] = load_series([NOMINAL], ["/imu/data:linear_acceleration.z"])
    frame = bagkit.read_dataframe(NOMINAL, "/imu/data", ["linear_acceleration.z"])
    assert np.array_equal(z.values, frame["linear_acceleration.z"].to_numpy())
    from bagkit.bag import BagReader

    with BagReader(NOMINAL) as reader:
        start = reader.start_ns
    assert np.allclose(z.times, (frame["log_time"].to_numpy() - start) / 1e9)
    assert z.unit == "m/s²"
    [absolute] = load_series([NOMINAL], ["/imu/data:linear_acceleration.z"], absolute=True)
    assert (absolute.times == frame.index.tz_convert(None).to_numpy()).all()


def test_decimation_keeps_every_spike() -> None:
    rng = np.random.default_rng(0)
    values = rng.normal(0, 1, 100_000)
    values[[123, 55_555, 99_999]] = [50, -60, 70]
    times = np.arange(len(values)) / 100.0
    kept_t, kept_v = decimate(times, values, 2000)
    assert len(kept_v) <= 2000 and np.all(np.diff(kept_t) > 0)
    assert {50.0, -60.0, 70.0} <= set(kept_v.tolist())


def test_bad_series_are_one_error_line(tmp_path: Path) -> None:
    result = _plot(NOMINAL, "/imu/data:nope", "-o", tmp_path / "x.png")
    assert result.returncode == 2 and "error: /imu/data has no field nope (it has" in result.stderr
    result = _plot(NOMINAL, "/imu/data:header.frame_id", "-o", tmp_path / "x.png")
    assert result.returncode == 2 and "is a string, not a number" in result.stderr
    result = _plot(NOMINAL, "/imu/data", "-o", tmp_path / "x.png")
    assert result.returncode == 2 and "is not TOPIC:FIELD" in result.stderr
    result = _plot(NOMINAL, "/imu/data:orientation.x", "-o", tmp_path / "x.pdf")
    assert result.returncode == 2 and "must end in .png or .html" in result.stderr
    assert "Traceback" not in result.stderr
