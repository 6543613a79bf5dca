"""The recorded meshcat replay of a pick (`scripts/pick.py --record`), opened in headless Chromium."""

import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
from pydrake.geometry import Meshcat, MeshcatParams

from diagrams.autonomous_pick import run_pick
from diagrams.scenario import replace_object

# ENVIRONMENT.md: what renders meshcat's WebGL page headless here (software GL, no network), plus `--timeout`:
# Chromium 156 (Debian's of 2026-11-26) never ends the 5 s of virtual time on a recorded pick's page (its animation
# plays), on an idle machine too; the real-time stop after 30 s ends it with the page drawn (4-13 s seen here).
CHROMIUM_FLAGS = (
    "--headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking "
    "--disable-component-update --disable-sync --enable-unsafe-swiftshader --window-size=1024,768 "
    "--virtual-time-budget=5000 --timeout=30000"
).split()


def screenshot(html: Path, tmp_path: Path) -> np.ndarray:
    """The page rendered by headless Chromium, H x W x 3 HSV (OpenCV's ranges: hue 0..180)."""
    chromium = shutil.which("chromium")
    assert chromium, "chromium is not installed: `make apt` installs it"
    png = html.with_suffix(".png")
    command = [
        chromium,
        *CHROMIUM_FLAGS,
        f"--user-data-dir={tmp_path / ('profile_' + html.stem)}",
        f"--screenshot={png}",
    ]
    subprocess.run([*command, html.as_uri()], check=True, capture_output=True, timeout=180)
    image = cv2.imread(str(png))
    assert image is not None, f"chromium wrote no screenshot {png}"
    return cv2.cvtColor(image, cv2.COLOR_BGR2HSV)


def coloured_pixels(hsv: np.ndarray, hue_range: tuple[int, int]) -> int:
    hue, saturation, value = (hsv[:, :, i].astype(int) for i in range(3))
    return int(np.count_nonzero((saturation > 100) & (value > 60) & (hue >= hue_range[0]) & (hue <= hue_range[1])))


@pytest.mark.slow
def test_recorded_pick_shows_the_scene_in_headless_chromium(scenario, tmp_path):
    meshcat = Meshcat(MeshcatParams(host="localhost"))
    html = tmp_path / "pick.html"
    outcome = run_pick(replace_object(scenario, instance="test_0", yaw=0.25), meshcat, record=html)
    assert outcome.success, outcome.message
    assert html.stat().st_size > 1_000_000  # self-contained: three.js and every mesh inside
    empty = tmp_path / "empty.html"
    empty.write_text(Meshcat(MeshcatParams(host="localhost")).StaticHtml())

    shot, blank = screenshot(html, tmp_path), screenshot(empty, tmp_path)
    changed = np.any(np.abs(shot.astype(int) - blank.astype(int)) > 30, axis=2).mean()
    assert changed > 0.2, f"only {changed:.1%} of the page differs from an empty scene"
    # The wooden table and the green can, framed by the station's camera pose (the empty page has neither).
    assert coloured_pixels(shot, (8, 25)) > 5000 > coloured_pixels(blank, (8, 25))
    assert coloured_pixels(shot, (45, 80)) > 500 > coloured_pixels(blank, (45, 80))
