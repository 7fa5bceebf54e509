"""scripts/screenshots.py makes the README's pictures of each screen from the example: it runs under
the tests' virtual X server and writes non-empty images of the sizes it promises."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

pytestmark = pytest.mark.usefixtures("xvfb_display")
SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "screenshots.py"


def _script():
    spec = importlib.util.spec_from_file_location("vebuild_screenshots", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_script_writes_each_screen_of_the_example(tmp_path, capsys):
    shots = _script()
    out = tmp_path / "images"
    assert shots.main(["--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for name, (window, width) in shots.SHOTS.items():
        im = Image.open(out / name)
        assert im.format == "PNG" and im.mode == "P"  # a palette: small files to commit
        if name == "demo-summary.png":  # the demo's last screen: 30 rows of a 110-column terminal
            assert im.width == width and 0.4 * width < im.height < 0.8 * width
        elif window is None:  # the report's first two A4 pages side by side, on grey
            a4 = 297 / 210
            assert im.width == width and im.height == pytest.approx(width / 2 * a4, rel=0.05)
        else:
            assert im.size == (width, round(window[1] * width / window[0]))
        assert (out / name).stat().st_size < 400_000
        pixels = np.asarray(im.convert("RGB")).astype(float)
        assert pixels.std() > 20  # a picture, not a blank frame
        assert name in printed
    assert not list(out.glob("*.part"))
    # The walk-through's two pictures differ where the panel was (right) and where the legend is (lower left).
    panel = np.asarray(Image.open(out / "view-panel.png").convert("RGB")).astype(int)
    present = np.asarray(Image.open(out / "view-present.png").convert("RGB")).astype(int)
    h, w, _ = panel.shape
    assert np.abs(panel[h // 4:3 * h // 4, -w // 5:] - present[h // 4:3 * h // 4, -w // 5:]).mean() > 20
    assert np.abs(panel[-h // 8:, :w // 4] - present[-h // 8:, :w // 4]).mean() > 20
    # The proposals (D) add dashed segments over the same photo.
    photo = np.asarray(Image.open(out / "edit-photo.png").convert("RGB")).astype(int)
    proposals = np.asarray(Image.open(out / "edit-proposals.png").convert("RGB")).astype(int)
    assert np.abs(photo - proposals).max(axis=2).__gt__(60).mean() > 0.01


def test_without_a_display_or_xvfb_run_it_says_what_to_install(monkeypatch, capsys):
    shots = _script()
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(shots.shutil, "which", lambda name: None)
    assert shots.main(["--out", "unused"]) == 2
    assert "apt-get install xvfb" in capsys.readouterr().err
    assert not Path("unused").exists()


def test_only_makes_the_one_photo_picture_with_its_two_measurements(tmp_path, capsys):
    shots = _script()
    out = tmp_path / "images"
    assert shots.main(["--out", str(out), "--only", "one-photo-measure.png"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["one-photo-measure.png"]
    assert "one-photo-measure.png" in capsys.readouterr().out
    im = Image.open(out / "one-photo-measure.png")
    (window, width) = shots.SHOTS["one-photo-measure.png"]
    assert im.mode == "P" and im.size == (width, round(window[1] * width / window[0]))
    # The two measurements' lines and dots in the Measure tool's cyan (MEASURE_COLOUR), on the photo.
    rgb = np.asarray(im.convert("RGB")).astype(int)
    cyan = (rgb[..., 2] > 200) & (rgb[..., 1] > 170) & (rgb[..., 0] < 120)
    assert cyan.sum() > 100


def test_only_makes_the_one_photo_walk_through_with_its_grid_and_height(tmp_path, capsys):
    shots = _script()
    out = tmp_path / "images"
    assert shots.main(["--out", str(out), "--only", "one-photo-view.png"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["one-photo-view.png"]
    im = Image.open(out / "one-photo-view.png")
    (window, width) = shots.SHOTS["one-photo-view.png"]
    assert im.mode == "P" and im.size == (width, round(window[1] * width / window[0]))
    rgb = np.asarray(im.convert("RGB")).astype(int)
    cyan = (rgb[..., 2] > 200) & (rgb[..., 1] > 170) & (rgb[..., 0] < 120)  # the height measured
    assert cyan.sum() > 50
    # The floor grid over the photo's floor (its lower third, left of the panel): near-white lines
    # on the tiles, which have none of their own.
    floor = rgb[2 * rgb.shape[0] // 3:, : rgb.shape[1] // 2]
    assert (floor.min(axis=2) > 215).sum() > 200
