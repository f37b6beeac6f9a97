"""The report in a real headless browser (issue 24): Chromium (Debian's, installed by the test
command of tools/setup.sh when run as root) loads index.html, takes a screenshot, and dumps the
page it rendered; the manifest is a table of what produced the numbers, every figure of the
page is an image file beside it, every table links its CSV."""
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

BROWSER = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome")
                if shutil.which(b)), None)


@pytest.mark.skipif(BROWSER is None, reason="no Chromium here (tools/setup.sh test installs "
                                            "Debian's chromium when run as root)")
def test_the_report_renders_in_headless_chromium(tmp_path, root):
    out = tmp_path / "report"
    subprocess.run([sys.executable, "-m", "mbdk", "report", "--quick", "--out", out,
                    "--studies", root / "studies", "--only", "ch4_tables"], check=True,
                   capture_output=True)
    page = (out / "index.html").as_uri()
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"]
    shot = tmp_path / "shot.png"
    subprocess.run([BROWSER, *flags, f"--screenshot={shot}", "--window-size=1280,2000", page],
                   check=True, capture_output=True, timeout=120)
    dom = subprocess.run([BROWSER, *flags, "--dump-dom", page], check=True, capture_output=True,
                         text=True, timeout=120).stdout
    import matplotlib.image
    pixels = matplotlib.image.imread(shot)
    assert pixels.shape[:2] == (2000, 1280)
    ink = np.mean(np.any(pixels[..., :3] < 0.9, axis=-1))
    assert ink > 0.05                      # text, tables and the figure, not a blank page
    assert "<table class=\"manifest\">" in dom and "compiler flags" in dom
    assert " -I " not in dom.split("</table>")[0]    # no include paths in the manifest
    images = re.findall(r"<img src=\"([^\"]+)\"", dom)
    assert images and all((out / src).read_bytes()[:4] == b"\x89PNG" for src in images)
    csvs = re.findall(r"<a href=\"([^\"]+\.csv)\"", dom)
    assert len(csvs) == 4 and all((out / c).is_file() for c in csvs)
