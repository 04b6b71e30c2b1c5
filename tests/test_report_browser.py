"""The run report and the preview gallery render in a real browser (headless Chromium screenshots).

Needs Debian's `chromium` package (`apt-get install -y chromium`); skipped with a reason otherwise.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from test_preview import make_preview_sample  # tests/ is on sys.path (rootdir conftest, no package)
from test_report import RECIPE, RUN_LOG, make_stats

pytestmark = pytest.mark.slow


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no chromium on PATH (Debian: apt-get install -y chromium)")


def screenshot(page: Path, png: Path, height: int = 2000) -> np.ndarray:
    """Headless Chromium screenshot of a local page at 1280 x height -> RGB array."""
    from PIL import Image

    with tempfile.TemporaryDirectory() as profile:
        cmd = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={profile}",
               "--hide-scrollbars", f"--screenshot={png}", f"--window-size=1280,{height}", page.resolve().as_uri()]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert png.is_file(), f"chromium wrote no screenshot (rc {r.returncode}): {r.stderr[-2000:]}"
    return np.asarray(Image.open(png).convert("RGB"))


def _not_blank(img: np.ndarray) -> None:
    assert img.shape[1] == 1280 and img.shape[0] >= 1000
    flat = img.reshape(-1, 3)
    assert flat.std(axis=0).max() > 20  # not one flat colour
    colours = np.unique(flat[:: 7] // 8, axis=0)
    assert len(colours) > 200  # plots / photos, not an empty page or an error page


def test_report_renders_in_chromium(tmp_path):
    from refspatial_gen.run.report import write_report

    page = write_report(tmp_path, make_stats(), RUN_LOG, RECIPE)
    img = screenshot(page, tmp_path / "report_shot.png")
    _not_blank(img)
    assert img[20:120, 20:600].mean() < 80  # the dark summary header is at the top
    # plot images loaded: the blue relation bars (#2171b5) appear in the first screen
    blue = np.all(np.abs(img.astype(int) - [0x21, 0x71, 0xB5]) < 12, axis=-1)
    assert blue.sum() > 2000, "relation plot not rendered"


def test_gallery_renders_in_chromium(tmp_path):
    from refspatial_gen.run import draw
    from refspatial_gen.run.preview import write_gallery

    stream = [(f"shard-{i}.mcap", make_preview_sample(seed=7 + i, sample_id=f"s{i}", frame_id=f"toy:{i}"))
              for i in range(2)]
    index = write_gallery(stream, tmp_path / "gallery", n=6, seed=0)
    img = screenshot(index, tmp_path / "gallery_shot.png")
    _not_blank(img)
    # the overlays are in the page: answer-marker magenta and table brown pixels are visible
    magenta = np.all(np.abs(img.astype(int) - draw.ANSWER) < 20, axis=-1)
    assert magenta.sum() > 20, "answer markers not visible in the gallery"
    brown = np.all(np.abs(img.astype(int) - [150, 110, 75]) < 40, axis=-1)
    assert brown.sum() > 20000, "preview images not rendered"
