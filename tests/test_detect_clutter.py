"""vebuild detect on street photos with clutter: the building's edges are proposed, the clutter is
not grouped into an axis, and the calibration from "accept all" is honest.

The photos are vebuild.bench.clutter_photos' (1600 × 1200, a façade near-frontal or oblique, with
cobbles, a tree, sagging wires, a stair railing or a sloped roof; cached like the bench's).
"""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.actions.detect import propose
from vebuild.bench.clutter_photos import clutter_photo, load, photo_record
from vebuild.calibration.clutter import curved, short, weak_direction
from vebuild.calibration.lines import _distances
from vebuild.calibration.photo import calibrate_photo
from vebuild.calibration.priors import FocalPrior
from vebuild.camera import Lens, undistort_pixels

#: A detected segment belongs to a true direction where its end points lie within this distance of
#: the line through its midpoint and the true vanishing point (px, undistorted by the true lens):
#: some 5× the detected segments' 1σ on these photos.
ON_LINE_PX = 1.5
#: ... and to none where it lies further than this from every true direction's line.
OFF_LINE_PX = 3.0
#: The coverage set: photos, and the share of true values inside their 95 % intervals it must
#: reach: 0.95 − 3 binomial σ (√(0.95 · 0.05 / 40) = 3.4 %): 84.7 %, the lower end of the band an
#: honest 95 % interval stays in 99.7 % of the time (measured: f 95.0 %, principal point 90.0 %).
COVERAGE_PHOTOS = 40
COVERAGE_MIN = 0.95 - 3 * np.sqrt(0.95 * 0.05 / COVERAGE_PHOTOS)


def _calibrated(i: int):
    gp = clutter_photo(i)
    t = gp.truth
    props = propose(load(gp), photo_record(gp, f"c{i:03d}"))
    segs: dict[str, list] = {}
    sig: dict[str, list] = {}
    for p in props.segments:
        segs.setdefault(p.axis, []).append(np.array(p.points))
        sig.setdefault(p.axis, []).append(p.sigma_px)
    prior = FocalPrior(t["exif_focal_px"], t["exif_focal_sigma_rel"] * t["exif_focal_px"], "exif")
    cal = calibrate_photo(segs, t["width"], t["height"], segment_sigma_px=sig, exif_focal=prior)
    return gp, props, cal


def _true_distances(props, truth, directions=None) -> dict[str, np.ndarray]:
    """Axis → (n, k) distances of its proposed segments to the lines through the true vanishing
    points (the three axes', or ``directions`` (3, k) world)."""
    K, R = np.array(truth["K"]), np.array(truth["R"])
    V = K @ R @ (np.eye(3) if directions is None else directions)
    out = {}
    for a in "xyz":
        ss = [p for p in props.segments if p.axis == a]
        if ss:
            seg = np.array([np.r_[p.points[:2], p.points[-2:]] for p in ss])
            u = undistort_pixels(K, seg.reshape(-1, 2), Lens(truth["k1"])).reshape(-1, 4)
            out[a] = _distances(u, V)
    return out


def _covered(gp, cal) -> tuple[bool, bool]:
    K = np.array(gp.truth["K"])
    f, s = cal.K[0, 0], np.sqrt(cal.covariance[0, 0])
    d = cal.K[:2, 2] - K[:2, 2]
    m2 = float(d @ np.linalg.solve(cal.covariance[1:3, 1:3], d))
    return bool(abs(f - K[0, 0]) <= 1.96 * s), bool(m2 <= 5.991)  # χ², 2 dof, 95 %


@pytest.mark.parametrize("i", [2, 20])
def test_near_frontal_facade_verticals_proposed_cobbles_not(i: int) -> None:
    """Near-frontal façades over a cobbled pavement: on today's main the cobbles' short edges were
    grouped into the third direction (photo 2: f +225 %, 45σ; photo 20: +30 %, 10σ)."""
    gp, props, cal = _calibrated(i)
    t = gp.truth
    assert t["kind"] == "frontal" and "cobbles" in t["clutter"]
    dist = _true_distances(props, t)
    side = max(t["width"], t["height"])
    # The long verticals (pilasters, downpipes) are proposed along z.
    z = [p for p in props.segments if p.axis == "z"]
    long_z = [p for p, d in zip(z, dist["z"], strict=True)
              if d[2] < ON_LINE_PX and np.hypot(p.points[-2] - p.points[0], p.points[-1] - p.points[1]) > 0.15 * side]
    assert len(long_z) >= 5, props.message
    # No proposed segment lies off its axis' true line: the clutter is in no axis.
    for a, d in dist.items():
        k = int(np.bincount(np.argmin(d, axis=1), minlength=3).argmax())
        assert np.all(d[:, k] < OFF_LINE_PX), (a, np.round(d[:, k], 1), props.message)
    f_ok, _ = _covered(gp, cal)
    assert f_ok, (cal.K[0, 0], np.array(t["K"])[0, 0], np.sqrt(cal.covariance[0, 0]), cal.mode, props.message)


def test_sloped_railing_and_roof_not_a_horizontal_axis() -> None:
    """A stair railing rising along the façade and a roof sloping back: their long straight edges
    meet at points off the horizontal axes, and none is proposed as x or y (on today's main, photos
    8 and 38 had 4 and 3 railing edges in their y axis)."""
    seen = 0
    for i in (3, 6, 8, 10, 38):
        gp = clutter_photo(i)
        t = gp.truth
        assert t["slopes"], t["clutter"]
        props = propose(load(gp), photo_record(gp, f"c{i:03d}"))
        on_slope = _true_distances(props, t, np.array(t["slopes"]).T)
        on_axes = _true_distances(props, t)
        for a in on_slope:
            sloped = (on_slope[a].min(axis=1) < ON_LINE_PX) & (on_axes[a].min(axis=1) > OFF_LINE_PX)
            assert not sloped.any(), (i, a, props.message)
            seen += 1
    assert seen >= 10


def test_coverage_over_cluttered_photos() -> None:
    """Detected, accepted all, calibrated with EXIF: the true focal length and principal point inside
    their 95 % intervals as often as the binomial noise of 40 photos allows (today's main: 67 % and
    56 %, errors up to +225 %)."""
    f_in, pp_in = [], []
    for i in range(COVERAGE_PHOTOS):
        gp, _, cal = _calibrated(i)
        f_ok, pp_ok = _covered(gp, cal)
        f_in.append(f_ok)
        pp_in.append(pp_ok)
    assert np.mean(f_in) >= COVERAGE_MIN, np.flatnonzero(~np.array(f_in))
    assert np.mean(pp_in) >= COVERAGE_MIN, np.flatnonzero(~np.array(pp_in))


def test_short_curved_and_weak_rules() -> None:
    """The rules themselves: a short edge, a bent polyline, too little length or a direction square
    to nothing."""
    segs = np.array([[0, 0, 30, 0], [0, 0, 300, 0.0]])
    assert short(segs, 1600, 1200).tolist() == [True, False]
    straight = np.array([[0, 0, 100, 0, 200, 0, 300, 0.0]])
    bent = np.array([[0, 0, 100, 3, 200, 3, 300, 0.0]])
    K = np.array([[1600.0, 0, 800], [0, 1600, 600], [0, 0, 1]])
    assert not curved(straight, np.array([0.3]), K, 0.0)[0]
    assert curved(bent, np.array([0.3]), K, 0.0)[0]
    c = np.array([800.0, 600.0])
    few = np.array([[100, 100, 150, 100], [100, 300, 150, 301], [100, 500, 150, 502.0]])
    assert "under" in (weak_direction(few, np.full(3, 0.3), 1600.0, c, 1600.0, None) or "")
    # Long segments meeting at (800, -2000): strong alone, but not square to a frame whose third
    # direction is the optical axis.
    v = np.array([800.0, -2000.0])
    ends = np.array([[200.0, 1100.0], [600.0, 1100.0], [1000.0, 1100.0], [1400.0, 1100.0]])
    far = ends + 0.3 * (v - ends)
    rows = np.c_[ends, far]
    assert weak_direction(rows, np.full(4, 0.3), 1600.0, c, 1600.0, None) is None
    why = weak_direction(rows, np.full(4, 0.3), 1600.0, c, 1600.0, np.array([0.0, 0.0, 1.0]))
    assert why is not None and "square" in why


def test_bench_detect_reports_the_street_photos() -> None:
    """`vebuild bench detect` scores the street photos too, and its table shows them."""
    from vebuild.bench import detect as bench
    from vebuild.bench.detect_clutter import clutter_figures

    fig, rows = clutter_figures(2)
    assert fig["clutter_photos"] == 2 and len(rows) == 2
    assert 0.0 <= fig["clutter_focal_coverage_95"] <= 1.0
    assert fig["clutter_not_calibrated"] + sum(r["covered"] is not None for r in rows) == 2
    text = bench.table(fig)
    assert "street photos with clutter" in text and "clutter_principal_point_coverage_95" in text


def test_edges_that_only_nearly_meet_are_not_a_direction() -> None:
    """Long edges that pass within 1–2 px of one point but whose 1σ is 0.3 px (clutter meeting
    there by chance) fail the χ² test; the same edges through the point exactly pass it."""
    c = np.array([800.0, 600.0])
    v = np.array([700.0, 650.0])
    starts = np.array([[100.0, 100.0], [1500.0, 150.0], [150.0, 1150.0], [1450.0, 1100.0], [800.0, 50.0]])
    exact = np.c_[starts, starts + 0.6 * (v - starts)]
    assert weak_direction(exact, np.full(5, 0.3), 1600.0, c, 1600.0, None) is None
    rng = np.random.default_rng(1)
    off = exact.copy()
    off[:, 2:] += rng.choice([-1.0, 1.0], (5, 1)) * 1.5 * np.array([[0.7, -0.7]])
    why = weak_direction(off, np.full(5, 0.3), 1600.0, c, 1600.0, None)
    assert why is not None and "χ²" in why
