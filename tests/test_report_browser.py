"""The report in a real headless browser (issues 24 and 39): Chromium (Debian's, installed by the
test command of tools/setup.sh when run as root) loads the front page and every study page of
a report, takes screenshots and dumps the pages it rendered. The front page is one screen of
findings (its content ends above 1200 px at 1280 px wide, also with all the studies' rows)
and carries the build manifest; every study page renders its figures with captions and its
tables; every link and image of every page resolves to a file of the report."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

BROWSER = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome")
                if shutil.which(b)), None)
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"]
needs_browser = pytest.mark.skipif(BROWSER is None, reason="no Chromium here (tools/setup.sh "
                                   "test installs Debian's chromium when run as root)")


def _shot(page: Path, png: Path, height: int) -> np.ndarray:
    """The page rendered 1280 px wide; RGB in [0, 1]."""
    subprocess.run([BROWSER, *FLAGS, f"--screenshot={png}", f"--window-size=1280,{height}",
                    page.as_uri()], check=True, capture_output=True, timeout=120)
    import matplotlib.image
    return matplotlib.image.imread(png)[..., :3]


def _dom(page: Path) -> str:
    return subprocess.run([BROWSER, *FLAGS, "--dump-dom", page.as_uri()], check=True,
                          capture_output=True, text=True, timeout=120).stdout


def _content_bottom(pixels: np.ndarray) -> int:
    """The last pixel row with anything drawn on it (the page's background is white)."""
    rows = np.flatnonzero(np.any(pixels < 0.9, axis=(1, 2)))
    return int(rows[-1]) + 1 if rows.size else 0


@pytest.fixture(scope="module")
def report(tmp_path_factory, root):
    out = tmp_path_factory.mktemp("report") / "report"
    subprocess.run([sys.executable, "-m", "mbdk", "report", "--quick", "--out", out,
                    "--studies", root / "studies", "--only", "ch4_tables", "pendulum"],
                   check=True, capture_output=True)
    return out


@needs_browser
def test_the_front_page_is_one_screen_of_findings_with_the_manifest(report, tmp_path):
    page = report / "index.html"
    pixels = _shot(page, tmp_path / "front.png", 3000)
    assert pixels.shape[:2] == (3000, 1280)
    assert 200 < _content_bottom(pixels) <= 1200
    dom = _dom(page)
    assert "<table class=\"manifest\">" in dom and "compiler flags" in dom
    assert " -I " not in dom.split("class=\"manifest\"")[1].split("</table>")[0]
    links = re.findall(r"<a href=\"([^\"]+\.html)\">", dom)
    assert links == ["ch4_tables.html", "pendulum.html"]
    # the chapter-4 study flags book values: its row says how many and the count is shown
    row = dom.split("ch4_tables.html")[1].split("</tr>")[0]
    assert re.search(r"<td class=\"n\">[1-9]\d*</td>", row)
    assert "printed value" in row
    assert "explicit Euler" in dom.split("pendulum.html")[1].split("</tr>")[0]


@needs_browser
def test_a_front_page_of_every_study_with_long_findings_fits_one_screen(tmp_path):
    """The layout's bound, not this run's: all the studies with titles and findings far longer
    than a line still end above 1200 px (each row one line, cut with an ellipsis)."""
    from mbdk.report import STUDIES, _front_page
    entries = [{"name": n, "title": f"{n}: " + "a long title of a study " * 5, "flagged": 3,
                "findings": ["a finding much longer than a line " * 8, "a second one"]}
               for n in STUDIES]
    # and the hard cases' lines, each far longer than a line too (five, as the studies name)
    for e, case in zip(entries, ("drift", "stiffness", "singular poses", "redundant joints",
                                 "gimbal lock")):
        e["hard_cases"] = {case: "a hard case met at length " * 12}
    manifest = {"version": "0", "compiler": "gfortran " * 10, "compiler_flags": "-O2 " * 30,
                "numpy": "2", "python": "3", "machine": "x86_64", "quick": False,
                "generated": "now", "total_seconds": 1.0}
    page = tmp_path / "index.html"
    page.write_text(_front_page(entries, manifest))
    pixels = _shot(page, tmp_path / "front.png", 3000)
    assert 400 < _content_bottom(pixels) <= 1200
    dom = _dom(page)
    hard = dom.split("class=\"front hard\"")[1].split("</table>")[0]
    assert re.findall(r"<a href=\"(\w+)\.html\">([\w ]+)</a>", hard) == [
        (STUDIES[0], "drift"), (STUDIES[1], "stiffness"), (STUDIES[2], "singular poses"),
        (STUDIES[3], "redundant joints"), (STUDIES[4], "gimbal lock")]


@needs_browser
def test_every_study_page_renders_with_captioned_figures_and_its_links_resolve(report, tmp_path):
    pages = sorted(report.glob("*.html"))
    assert [p.name for p in pages] == ["ch4_tables.html", "index.html", "pendulum.html"]
    for page in pages:
        dom = _dom(page)
        targets = re.findall(r"(?:href|src)=\"([^\"#]+)", dom)
        assert targets, page.name
        for t in targets:
            assert (report / t).is_file(), (page.name, t)
        if page.name == "index.html":
            continue
        pixels = _shot(page, tmp_path / f"{page.stem}.png", 2000)
        assert np.mean(np.any(pixels < 0.9, axis=-1)) > 0.05      # text, tables and figures
        assert "<h1>" in dom and "href=\"index.html\"" in dom
        images = re.findall(r"<img src=\"([^\"]+)\"", dom)
        assert images and all((report / s).read_bytes()[:4] == b"\x89PNG" for s in images)
        captions = re.findall(r"<figcaption>(.*?)</figcaption>", dom, re.S)
        assert len(captions) == len(images)
        csvs = re.findall(r"<a href=\"([^\"]+\.csv)\"", dom)
        assert csvs and all((report / c).is_file() for c in csvs)
        if page.name == "pendulum.html":
            # the study's own captions: what the figure shows and what to read from it
            assert all(len(c) > 150 and "Read" in c for c in captions)
        else:
            # a flagged book value is highlighted in its table
            assert "<tr class=\"flag\">" in dom
