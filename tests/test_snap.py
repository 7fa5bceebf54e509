"""Snapping (vebuild.edit.snap, the session's snap calls): a click near a generated image's corner
or edge lands on its known sub-pixel position, within a tolerance made from the image's noise; a
drawn segment is refined to the line, its σ from the fit; Alt (exact) places where the cursor is;
snapping never moves a point farther than SNAP_RADIUS_PX; a flat photo snaps nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf

from vebuild.edit.snap import SNAP_RADIUS_PX, noise_sigma, refine_segment, snap_corner, snap_edge, snap_point

NOISE = 2.0  # grey levels, 1σ (a well-exposed JPEG's)
BLUR = 1.0  # px, the lens and sensor's blur
ANGLE = 0.3  # rad: edges not along the pixel grid
#: Förstner's estimate on a blurred L-corner keeps a small bias toward the corner's inside (about
#: 0.1 px at 1 px of blur, measured without noise); the tolerance is that plus 4σ of the noise.
CORNER_BIAS_PX = 0.12


def corner_image(c, rng, size=64, noise=NOISE):
    """A bright quadrant (its corner at c, rotated by ANGLE) on a dark ground, blurred, with noise."""
    j, i = np.mgrid[0:size, 0:size]
    u, v = i + 0.5, j + 0.5  # pixel centres (DESIGN.md)
    ca, sa = math.cos(ANGLE), math.sin(ANGLE)
    x = ca * (u - c[0]) + sa * (v - c[1])
    y = -sa * (u - c[0]) + ca * (v - c[1])
    f = 0.25 * (1 + erf(x / (BLUR * math.sqrt(2)))) * (1 + erf(y / (BLUR * math.sqrt(2))))
    return (60 + 120 * f + rng.normal(0, noise, f.shape)).astype(np.float32)


NORMAL = np.array([math.cos(ANGLE), math.sin(ANGLE)])  # across the edge x = 0
ALONG = np.array([-math.sin(ANGLE), math.cos(ANGLE)])  # along it, away from the corner


def test_the_noise_estimate_finds_the_noise_added():
    img = corner_image((30, 30), np.random.default_rng(0))
    assert noise_sigma(img) == pytest.approx(NOISE, rel=0.15)


def test_a_click_near_a_corner_lands_on_it_within_its_noise():
    rng = np.random.default_rng(1)
    errs, sigmas = [], []
    for _ in range(30):
        c = np.array([30.0, 31.0]) + rng.uniform(0, 1, 2)
        img = corner_image(c, rng)
        click = c + rng.uniform(-2, 2, 2)
        s = snap_corner(img, click)
        assert s is not None and s.kind == "corner"
        assert s.moved_px <= SNAP_RADIUS_PX
        errs.append(float(np.linalg.norm(np.asarray(s.uv) - c)))
        sigmas.append(s.sigma_px)
    sigma = float(np.mean(sigmas))
    assert 0.01 < sigma < 0.3  # a fraction of a pixel, not nothing
    assert max(errs) < CORNER_BIAS_PX + 4 * sigma
    rms = math.sqrt(np.mean(np.square(errs)))
    assert rms < CORNER_BIAS_PX + 2 * sigma


def test_a_click_near_an_edge_moves_onto_it_along_its_normal():
    rng = np.random.default_rng(2)
    errs, sigmas = [], []
    for _ in range(30):
        c = np.array([30.0, 20.0]) + rng.uniform(0, 1, 2)
        img = corner_image(c, rng)
        on = c + 20 * ALONG
        click = on + rng.uniform(-2.5, 2.5) * NORMAL
        s = snap_point(img, click)  # no corner there: the edge
        assert s is not None and s.kind == "edge"
        # along the normal only (as the patch estimates it: within a few degrees of the true one)
        assert abs((np.asarray(s.uv) - click) @ ALONG) < 0.1 * s.moved_px + 1e-6
        errs.append(float((np.asarray(s.uv) - on) @ NORMAL))
        sigmas.append(s.sigma_px)
    sigma = float(np.mean(sigmas))
    rms = math.sqrt(np.mean(np.square(errs)))
    assert 0.005 < sigma < 0.2
    assert rms < 3 * sigma + 0.02 and max(np.abs(errs)) < 5 * sigma + 0.05
    assert abs(np.mean(errs)) < 2 * sigma  # no bias


def test_nothing_to_snap_to_far_from_an_edge_or_on_a_flat_patch():
    rng = np.random.default_rng(3)
    img = corner_image((30.4, 20.2), rng)
    assert snap_point(img, (30.4 + 15 * NORMAL[0] - 20 * ALONG[0], 50.0)) is None  # flat: the bright inside
    flat = rng.normal(100, NOISE, (64, 64)).astype(np.float32)
    assert snap_point(flat, (32.0, 32.0)) is None
    # An edge 5 px from the click is beyond the radius: the click stays.
    on = np.array([30.4, 20.2]) + 20 * ALONG
    assert snap_edge(img, on + (SNAP_RADIUS_PX + 2.0) * NORMAL) is None
    assert snap_point(np.zeros((64, 64), np.float32), (2.0, 2.0)) is None  # at the border


def test_a_drawn_segment_is_refined_to_the_line_with_its_sigma_from_the_fit():
    rng = np.random.default_rng(4)
    errs, sigmas = [], []
    for _ in range(12):
        c = np.array([50.0, 5.0]) + rng.uniform(0, 1, 2)
        img = corner_image(c, rng, size=80)
        a, b = c + 10 * ALONG + 1.5 * NORMAL, c + 60 * ALONG - 1.2 * NORMAL  # drawn 1.5 px off, askew
        fit = refine_segment(img, [*a, *b])
        assert fit is not None and fit.points >= 20
        ends = np.array(fit.segment).reshape(2, 2)
        errs += [float((e - c) @ NORMAL) for e in ends]
        sigmas.append(fit.sigma_px)
        assert fit.moved_px == pytest.approx(1.5, abs=0.3)
    # σ is at least the floor of 0.1 px; the ends lie within it of the true line.
    assert all(0.1 <= s < 0.3 for s in sigmas)
    assert max(np.abs(errs)) < 2 * max(sigmas)


def test_the_session_snaps_a_marker_and_alt_places_it_exactly(tmp_path):
    from PIL import Image

    from vebuild.edit.session import EditSession
    from vebuild.project import new_project, save_project

    rng = np.random.default_rng(5)
    c = np.array([40.3, 30.6])
    img = corner_image(c, rng, size=96)
    Image.fromarray(np.clip(img, 0, 255).astype(np.uint8)).convert("RGB").save(tmp_path / "c.png")
    save_project(tmp_path / "p.vebuild.json", new_project("snap"))
    s = EditSession.open(tmp_path / "p.vebuild.json", autosave=False)
    pid = s.add_photo(tmp_path / "c.png")
    click = (41.5, 29.8)
    uv, snapped = s.snap(pid, click)
    assert snapped is not None and np.linalg.norm(np.asarray(uv) - c) < 0.35  # 8-bit rounding adds its own noise
    assert s.snap(pid, click, exact=True) == (click, None)
    # A segment drawn along the edge: refined, its σ written beside it; undone with the rest.
    a, b = c + 10 * ALONG + 1.0 * NORMAL, c + 55 * ALONG - 1.0 * NORMAL
    p1, p2, fit = s.snap_segment(pid, a, b)
    assert fit is not None
    i = s.add_segment(pid, "y", p1, p2, sigma_px=fit.sigma_px)
    assert s.segment_sigma(pid, "y", i) == pytest.approx(fit.sigma_px, abs=1e-4)
    j = s.add_segment(pid, "y", a, b)  # a click's: null beside it
    assert s.photo(pid)["vanishing_segment_sigmas"]["y"] == [pytest.approx(fit.sigma_px, abs=1e-4), None]
    s.delete_segment(pid, "y", i)
    assert s.photo(pid)["vanishing_segment_sigmas"]["y"] == [None] and j == 1
    s.undo()
    s.undo()
    assert "vanishing_segment_sigmas" in s.photo(pid)
    s.undo()
    assert "vanishing_segment_sigmas" not in s.photo(pid)
