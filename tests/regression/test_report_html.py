"""report.html of a failing fixture, rendered by real headless Chromium: self-contained, with
the verdict table and, per failing field, golden vs candidate with the band and the difference."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from chromium import dump_dom, screenshot
from doubler_fixture import write_core, write_fixture
from PIL import Image

from bagkit.regression.artefacts import write_failure_artefacts
from bagkit.regression.golden import check_lockstep, update_golden
from bagkit.regression.spec import load_spec


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The report of the doubler fixture run with factor 2.5 against a golden of 2.0."""
    root = tmp_path_factory.mktemp("html")
    write_core(root)
    fixture = write_fixture(root / "fixtures" / "ramp")
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(root))
        update_golden(load_spec(fixture))
        spec_file = fixture / "spec.yaml"
        spec = yaml.safe_load(spec_file.read_text())
        spec["processor_args"] = {"factor": 2.5}
        spec_file.write_text(yaml.safe_dump(spec))
        check = check_lockstep(load_spec(fixture), root / "work")
        assert not check.passed
        write_failure_artefacts(check, root / "failure")
    return root / "failure" / "report.html"


def test_the_page_needs_no_network(report: Path) -> None:
    text = report.read_text()
    # the only URL is the SVG namespace, which names and fetches nothing
    urls = set(re.findall(r"https?://[^\"' >]+", text))
    assert urls == {"http://www.w3.org/2000/svg"}
    assert "<script src" not in text and "<link" not in text
    assert len(text) < 300_000


def test_chromium_renders_the_verdict_and_the_plots(report: Path) -> None:
    dom = dump_dom(report)
    assert "ramp (lockstep): FAIL" in dom
    verdict = dom[dom.index('id="verdict"') : dom.index("</table>")]
    rows = re.findall(r"<tr>(.*?)</tr>", verdict)
    assert len(rows) == 3  # the header, /doubled, /sum
    doubled = next(r for r in rows if "/doubled" in r)
    assert "FAIL" in doubled and "data (max |err|" in doubled
    assert "pass" in next(r for r in rows if "/sum" in r)
    # one failing field: values with band, and the difference with band
    assert dom.count('class="plot"') == 2
    assert 'aria-label="/doubled data values"' in dom
    assert 'aria-label="/doubled data difference"' in dom
    for element in ('class="golden"', 'class="candidate"', 'class="difference"'):
        assert dom.count(element) == 1, element
    assert dom.count('class="band"') == 2


def test_the_screenshot_is_not_blank(report: Path, tmp_path: Path) -> None:
    png = screenshot(report, tmp_path / "report.png")
    pixels = np.asarray(Image.open(png).convert("L"), dtype=float)
    assert pixels.shape == (1400, 1000)
    assert pixels.std() > 10  # a blank or one-colour page is about 0
    # the plot area (below the table) holds the coloured lines, not just background
    colours = np.asarray(Image.open(png).convert("RGB"))[300:900].reshape(-1, 3)
    assert len(np.unique(colours, axis=0)) > 20
