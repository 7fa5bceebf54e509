"""`vebuild export PROJECT --html DIR` on a project with no model: the web viewer shows its one
calibrated photo at the photo's own camera (the camera-only glTF of vebuild/render/export_camera.py,
opened by three.js in a real headless Chromium, tests/chromium_cdp.py), with the floor grid and the
saved measurements over it, and they line up with the photo.

The photo is generated: black, with a red dot where the lens (k1 = −0.04, the principal point off
centre) puts each floor point at the centre of a grid cell. The screenshot (the window the photo's
size, so one screen pixel is one photo pixel) is read against vebuild's own pinhole projection of
the same points computed here: the dots (the photo, undistorted by the photo plane), the grid lines
and the measurement lines (drawn by three.js) must each lie within 1 px of it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from chromium_cdp import Browser, find_chromium
from handoff_project import DOT_PX, make_project
from PIL import Image
from scipy import ndimage

from vebuild.camera import Lens
from vebuild.camera import project as project_points
from vebuild.cli import main

CHROMIUM = find_chromium()
#: The claim: the photo, the floor and the measurements line up within this (screen = photo pixels).
ALIGN_PX = 1.0
#: A line's end is read as the last pixel whose centre is lit at half strength or more: that pixel's
#: centre lies up to half a pixel from the end it draws, so ends are held to ALIGN_PX plus this.
END_QUANTUM_PX = 0.5
K1 = -0.04
LOAD_S = 60
STATE = "JSON.parse(document.getElementById('vebuild-state').textContent)"
READY = f"(function(){{var s={STATE};return s.errors.length>0||(s.stage==='running'&&s.frames>3);}})()"
#: Hide the panel and the labels, which cover the picture (what the H key and clean=1 do, minus the lines).
BARE = "document.getElementById('panel').style.display='none';document.getElementById('labels').style.display='none';1"


#: Every test here shares `page`: they run in one pytest-xdist worker (`--dist loadgroup`,
#: pyproject's addopts), so that it is computed once, not once per worker.
pytestmark = pytest.mark.xdist_group("export_html_single_photo.page")


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    if CHROMIUM is None:
        pytest.skip("the HTML viewer's tests need a headless Chromium: `apt-get install chromium`")
    h = make_project(tmp_path_factory.mktemp("html-one-photo"), k1=K1, dots=True)
    out = h.path.parent / "viewer"
    assert main(["export", str(h.path), "--html", str(out)]) == 0
    browser = Browser(CHROMIUM, h.cam.width, h.cam.height)
    try:
        browser.open((out / "index.html").as_uri())
        browser.wait_for(READY, LOAD_S)
        state = browser.evaluate(STATE)
        browser.evaluate(BARE)
        browser.wait_for(f"{STATE}.frames > {state['frames'] + 3}", 20)
        shot = np.asarray(Image.open(browser.screenshot(h.path.parent / "page.png")).convert("RGB")).astype(float)
    finally:
        browser.close()
    return h, out, state, shot


def _segments(h, out) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The grid, axes and measurement segments of the exported scene (world, (n, 2, 3) each)."""
    from vebuild.render.export import read_glb
    from vebuild.render.export_camera import grid_lines

    doc, _ = read_glb((out / "scene.glb").read_bytes())
    nodes = {n["name"]: n for n in doc["nodes"]}
    ex = nodes["floor grid (z = 0)"]["extras"]
    grid = grid_lines(ex["spacing"], tuple(ex["bounds_xy"]))
    axes = np.array([[[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [0, 1, 0]], [[0, 0, 0], [0, 0, 1]]], float)
    measures = np.array([n["extras"]["ends"] for n in doc["nodes"] if (n.get("extras") or {}).get("vebuild_role")
                         == "measurement"], float)
    return grid, axes, measures


def _clip(cam, seg: np.ndarray) -> np.ndarray | None:
    """A world segment's pinhole image (2, 2), clipped to the part at least 0.3 in front of the camera."""
    R, C = np.asarray(cam.R), np.asarray(cam.C)
    z = (seg - C) @ R[2]
    if z.max() < 0.3:
        return None
    a, b = seg
    if z[0] < 0.3:
        a = a + (b - a) * (0.3 - z[0]) / (z[1] - z[0])
    if z[1] < 0.3:
        b = b + (a - b) * (0.3 - z[1]) / (z[0] - z[1])
    return project_points(cam.K, cam.R, cam.C, np.array([a, b]))


def _distance(p: np.ndarray, segs: list[np.ndarray]) -> np.ndarray:
    """Distance of each point p (n, 2) to the nearest of the image segments."""
    best = np.full(len(p), np.inf)
    for a, b in segs:
        d = b - a
        t = np.clip(((p - a) @ d) / max(d @ d, 1e-12), 0, 1)
        best = np.minimum(best, np.linalg.norm(p - (a + t[:, None] * d), axis=1))
    return best


def _profile_offsets(img: np.ndarray, line: np.ndarray, keep: np.ndarray | None, step: float = 25.0,
                     half: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Across the image segment ``line``, at points every ``step`` px: the offset (px) of the
    intensity centroid of ``img`` from the line, and the points. ``keep(points)`` filters them."""
    a, b = line
    L = float(np.linalg.norm(b - a))
    d = (b - a) / L
    n = np.array([-d[1], d[0]])
    t = np.arange(step / 2, L - step / 2, step)
    pts = a + t[:, None] * d
    H, W = img.shape
    ok = (pts[:, 0] > half + 2) & (pts[:, 0] < W - half - 2) & (pts[:, 1] > half + 2) & (pts[:, 1] < H - half - 2)
    if keep is not None:
        ok &= keep(pts)
    pts = pts[ok]
    s = np.arange(-half, half + 0.001, 0.25)
    q = pts[:, None, :] + s[None, :, None] * n  # (k, m, 2) screen coordinates
    # pixel (i, j) covers [i, i+1): its centre is at i + 0.5
    vals = ndimage.map_coordinates(img, [q[..., 1].ravel() - 0.5, q[..., 0].ravel() - 0.5], order=1)
    vals = vals.reshape(q.shape[:2])
    vals = np.maximum(vals - np.median(vals, axis=1, keepdims=True), 0)
    strong = vals.sum(1) > 0
    return (vals[strong] @ s) / vals[strong].sum(1), pts[strong]


def test_page_shows_the_photo_at_its_camera_with_no_error(page):
    h, out, state, shot = page
    assert state["errors"] == [] and state["camera"]["id"] == "photo-p"  # it opens at the photo's own camera
    assert state["viewport"] == [h.cam.width, h.cam.height]
    data = (out / "data.js").read_text()
    assert '"single_photo":true' in data
    analyses = json.loads(data[data.index("=") + 1:].rstrip().rstrip(";"))["analyses"]
    assert [a["name"] for a in analyses] == ["box height", "F1 to F2"]
    assert all(a["label"].startswith(a["name"] + ": ") and "(1σ), 95 %" in a["label"] for a in analyses)


def test_the_photo_lines_up_with_the_camera_within_1px(page):
    """Each red dot of the photo (drawn where the lens put its floor point) appears where the pinhole
    camera puts that point: the photo plane undid the lens and the principal point's offset."""
    h, out, _, shot = page
    grid, axes, measures = _segments(h, out)
    lines = [s for s in (_clip(h.cam, g) for g in [*grid, *axes, *measures]) if s is not None]
    want = project_points(h.cam.K, h.cam.R, h.cam.C, h.dots)  # pinhole: no k1
    clear = _distance(want, lines) > DOT_PX + 4  # dots no line crosses
    red = shot[..., 0] - shot[..., 1]
    labels, n = ndimage.label(red > 60)
    centres = np.array(ndimage.center_of_mass(np.maximum(red, 0), labels, range(1, n + 1)))[:, ::-1] + 0.5
    err = np.array([np.min(np.linalg.norm(centres - w, axis=1)) for w in want[clear]])
    assert clear.sum() >= 40, clear.sum()
    assert np.max(err) < ALIGN_PX, (np.max(err), np.median(err))
    # Had the plane ignored the lens, the dots near the corners would be off by many pixels.
    lens = project_points(h.cam.K, h.cam.R, h.cam.C, h.dots[clear], Lens(K1))
    assert np.max(np.linalg.norm(lens - want[clear], axis=1)) > 5 * ALIGN_PX


def test_the_floor_grid_and_the_measurements_line_up_within_1px(page):
    h, out, _, shot = page
    grid, axes, measures = _segments(h, out)
    grey = shot.min(axis=2)  # grid lines are grey; the red dots, the blue axis and the black photo are not
    cyan = np.clip(np.minimum(shot[..., 1], shot[..., 2]) - shot[..., 0], 0, None)
    images = [s for s in (_clip(h.cam, g) for g in grid) if s is not None]
    others = [s for s in (_clip(h.cam, g) for g in [*axes, *measures]) if s is not None]
    dots = project_points(h.cam.K, h.cam.R, h.cam.C, h.dots)
    offsets = []
    for i, line in enumerate(images):
        rest = images[:i] + images[i + 1:] + others

        def keep(p, rest=rest):
            far = _distance(p, rest) > 7
            return far & (np.min(np.linalg.norm(p[:, None] - dots[None], axis=2), axis=1) > DOT_PX + 6)

        off, _ = _profile_offsets(grey, line, keep)
        offsets.extend(off)
    offsets = np.abs(np.array(offsets))
    assert len(offsets) >= 100 and np.max(offsets) < ALIGN_PX, (len(offsets), np.max(offsets), np.median(offsets))
    for seg in measures:
        line = _clip(h.cam, seg)
        assert line is not None
        rest = images + [s for s in others if not np.allclose(s, line)]
        off, pts = _profile_offsets(cyan, line, lambda p, rest=rest: _distance(p, rest) > 7, step=8.0)
        assert len(off) >= 5 and np.max(np.abs(off)) < ALIGN_PX, off
        # Its ends: the cyan pixels along the line stop where the line's ends project.
        d = (line[1] - line[0]) / np.linalg.norm(line[1] - line[0])
        ys, xs = np.nonzero(cyan > 0.5 * cyan.max())
        p = np.c_[xs, ys] + 0.5
        length = float(np.linalg.norm(line[1] - line[0]))
        along = (p - line[0]) @ d
        near = (np.abs((p - line[0]) @ np.array([-d[1], d[0]])) < 2) & (along > -10) & (along < length + 10)
        t = along[near]
        ends = np.array([t.min(), t.max() - length])
        assert np.max(np.abs(ends)) < ALIGN_PX + END_QUANTUM_PX, (ends, length)
