"""Robust vanishing points (vebuild/calibration/robust.py): segments grouped into an axis they do
not belong to (cobblestone edges, roof and dormer slopes, a second building a few degrees off
square) are rejected and reported, not averaged in; an axis whose segments are mostly clutter is
left out (the weaker mode, said in the mode reason), and a photo left with one axis is refused.

The photos are vebuild.synthetic's realistic ones (barrel distortion, principal point and EXIF
off) with vebuild.synthetic.clutter's clutter, which records which segments are clutter.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from vebuild.calibration.photo import FocalPrior, calibrate_photo
from vebuild.calibration.robust import breakdown_tolerance
from vebuild.errors import CalibrationError
from vebuild.synthetic import CLICK_NOISE_PX, SyntheticPhoto, add_segments, realistic_camera
from vebuild.synthetic.clutter import add_clutter

#: |error| / reported 1σ that no photo may exceed (as in test_calibration: a 1-in-10⁵ draw).
UNCERTAINTY_BOUND = 4.5
Z95 = 1.959964
KINDS = ("3vp", "2vp", "frontal", "corridor")
#: The clutter mixed into the coverage batch, one class per photo in turn (kind, axis, count), each
#: below the breakdown point of an axis of 4–6 segments (vebuild.synthetic.add_segments).
CLUTTER = (None, ("cobblestones", "z", 4), ("slopes", "x", 2), ("slopes", "z", 2), ("not_square", "y", 2),
           ("cobblestones", "y", 3))
N_COVERAGE = 400
#: With n photos the share inside its 95 % interval has a sampling 1σ of √(0.95 · 0.05 / n): 1.09 %
#: at n = 400; the band is ± 2.2 of it, as tests/test_calibration_coverage.py's.
COVERAGE_BAND = (0.926, 0.974)


def _calibrate(ph: SyntheticPhoto, exif: bool = True):
    prior = FocalPrior(ph.exif_focal_px, ph.exif_focal_sigma_rel * ph.exif_focal_px, "exif") \
        if exif and ph.exif_focal_px else None
    return calibrate_photo(ph.segments, ph.width, ph.height, photo=ph.id, click_sigma_px=CLICK_NOISE_PX,
                           exif_focal=prior)


def _z_focal(ph: SyntheticPhoto, cal) -> float:
    return float((cal.f - ph.K[0, 0]) / cal.f_sigma)


def _rejected(cal, axis: str) -> set[int]:
    return {r.index for r in cal.rejected_segments.get(axis, ())}


def test_slopes_and_a_second_building_are_rejected_and_reported() -> None:
    """Long edges off the axis (roof slopes 25–45°, a second building 4° off square), two of an
    axis' 6–8: every slope rejected, and every edge of the second building that its line can tell
    (off by more than 4× the click noise), reported by index with its misfit and said in the mode
    reason; the focal length within its bound. Without the rejection the slopes pull f by tens of
    its 1σ."""
    rng = np.random.default_rng(4401)
    for i in range(24):
        ph = realistic_camera(rng, "3vp", photo_id=f"s{i}")
        add_segments(ph, rng, CLICK_NOISE_PX, middle_points=2)
        kind, axis = [("slopes", "x"), ("not_square", "x"), ("slopes", "y")][i % 3]
        clutter = add_clutter(ph, rng, kind, axis, 2)
        cal = _calibrate(ph, exif=False)
        if kind == "slopes":
            assert set(clutter) <= _rejected(cal, axis), (i, kind, cal.rejected_segments)
        else:  # an edge 4° off may lie where that changes its line by less than the click noise
            assert _rejected(cal, axis) & set(clutter), (i, kind, cal.rejected_segments)
        for k in set(clutter) - _rejected(cal, axis):
            assert abs(cal.segment_residuals_px[axis][k]) < 4 * CLICK_NOISE_PX
        assert "left out" not in cal.mode_reason, (i, kind, cal.mode_reason)
        for r in cal.rejected_segments[axis]:
            assert r.misfit_sigmas > 2.0 and "off its vanishing point beyond" in r.reason
        listed = ", ".join(str(r.index) for r in cal.rejected_segments[axis])
        assert f"of {len(ph.segments[axis])} {axis} segments rejected ({listed})" in cal.mode_reason
        assert abs(_z_focal(ph, cal)) < UNCERTAINTY_BOUND, (i, kind)
        # The rejected segments' residuals are still reported, index for index with the marks,
        # and the RMS is that of the segments kept.
        assert len(cal.segment_residuals_px[axis]) == len(ph.segments[axis])
        kept = np.concatenate([cal.kept_residuals_px(a) for a in "xyz"])
        assert cal.rms_px == pytest.approx(float(np.sqrt(np.mean(kept**2))))


def test_honest_segments_are_rarely_rejected() -> None:
    """The outlier test's family-wise α is 1 % a photo (robust.OUTLIER_ALPHA): of 80 photos with no
    clutter, at most 4 lose a segment (the binomial's 99.9 % quantile at p = 0.01 is 4), and none
    loses an axis."""
    rng = np.random.default_rng(4402)
    lost = 0
    for i in range(80):
        ph = realistic_camera(rng, KINDS[i % 2], photo_id=f"h{i}")
        add_segments(ph, rng, CLICK_NOISE_PX, middle_points=2)
        cal = _calibrate(ph)
        lost += bool(cal.rejected_segments)
        assert "left out" not in cal.mode_reason
    assert lost <= 4


def test_near_frontal_facade_with_clutter_in_the_third_direction_is_not_3vp() -> None:
    """A level camera facing a façade (the verticals parallel in the photo): three true verticals
    and, grouped with them, a pavement's cobblestone edges and two sloping dormer edges. Before,
    the clutter made the vertical vanishing point look finite: "3vp", f and c off by many 1σ. The
    clutter is more than an axis of 3 + 8 + 2 segments tolerates (breakdown_tolerance(13) = 5):
    the vertical axis is left out, the photo is 2vp, and f holds its interval."""
    rng = np.random.default_rng(4403)
    z, refused = [], 0
    for i in range(20):
        ph = realistic_camera(rng, "2vp", photo_id=f"f{i}")
        add_segments(ph, rng, CLICK_NOISE_PX, middle_points=2)
        ph.segments["z"] = list(ph.segments["z"])[:3]
        add_clutter(ph, rng, "cobblestones", "z", 8)
        add_clutter(ph, rng, "slopes", "z", 2)
        assert 10 > breakdown_tolerance(13)
        try:
            cal = _calibrate(ph)
        except CalibrationError as e:  # refused, never a tight wrong answer
            assert "do not meet at one vanishing point" in str(e)
            refused += 1
            continue
        assert cal.mode != "3vp", (i, cal.mode_reason)
        assert "axis z left out" in cal.mode_reason
        assert len(cal.rejected_segments["z"]) == 13
        z.append(_z_focal(ph, cal))
        d = cal.principal_point - ph.K[:2, 2]
        assert float(d @ np.linalg.solve(cal.covariance[1:3, 1:3], d)) < UNCERTAINTY_BOUND**2
    z = np.array(z)
    assert refused <= 2
    assert np.max(np.abs(z)) < UNCERTAINTY_BOUND
    assert np.mean(np.abs(z) < Z95) >= 0.85  # 18–20 photos: 85 % or more inside (binomial 1σ 5 %)


def test_clutter_below_the_breakdown_point_is_found_whatever_it_does() -> None:
    """An axis of 9 segments tolerates breakdown_tolerance(9) = 3 that do not belong: 3 parallel
    slopes (a consistent wrong vanishing point, the hardest kind) are all rejected and the rest kept."""
    assert [breakdown_tolerance(n) for n in (2, 3, 4, 6, 9, 10)] == [0, 0, 1, 2, 3, 4]
    rng = np.random.default_rng(4404)
    for i in range(12):
        ph = realistic_camera(rng, "3vp", photo_id=f"b{i}")
        add_segments(ph, rng, CLICK_NOISE_PX, per_axis=(6, 6), middle_points=2)
        clutter = add_clutter(ph, rng, "slopes", "x", 3)
        cal = _calibrate(ph)
        assert _rejected(cal, "x") == set(clutter), (i, cal.rejected_segments)
        assert abs(_z_focal(ph, cal)) < UNCERTAINTY_BOUND


def test_clutter_above_the_breakdown_point_refuses_a_two_axis_photo() -> None:
    """Two axes, one of them mostly slopes (4 true, 6 along three roof pitches: above
    breakdown_tolerance(10) = 4): no tight wrong answer, but a refusal that says which axis and
    what to do. (A consistent majority, all along one wrong direction, cannot be told from the
    axis by any estimator: that is what the breakdown point states.)"""
    rng = np.random.default_rng(4405)
    ph = realistic_camera(rng, "3vp", photo_id="two")
    add_segments(ph, rng, CLICK_NOISE_PX, per_axis=(4, 4), middle_points=2)
    del ph.segments["z"]
    for _ in range(3):
        add_clutter(ph, rng, "slopes", "x", 2)
    with pytest.raises(CalibrationError) as err:
        _calibrate(ph)
    text = str(err.value)
    assert "photo 'two'" in text and "do not meet at one vanishing point" in text
    assert "more than the 4 a robust fit can tell from clutter" in text


@pytest.fixture(scope="module")
def cluttered_batch():
    rng = np.random.default_rng(20261207)
    out = []
    for i in range(N_COVERAGE):
        ph = realistic_camera(rng, KINDS[i % len(KINDS)], photo_id=f"c{i}")
        add_segments(ph, rng, CLICK_NOISE_PX, middle_points=2)
        cl = CLUTTER[i % len(CLUTTER)]
        if cl is not None:
            add_clutter(ph, rng, cl[0], cl[1], cl[2])
        out.append((ph, _calibrate(ph)))
    return out


def test_intervals_hold_the_truth_with_clutter_mixed_in(cluttered_batch) -> None:
    """Photos of every kind, five in six with clutter grouped into one axis: the 95 % intervals of
    f, the principal point (2D ellipse) and the rotation (3D ellipsoid) hold the truth 95 % of the
    time within COVERAGE_BAND. Before, the clutter was averaged in: on 300 such photos f's interval
    held it 74 % of the time, the principal point's 62 %, the rotation's 67 %, f off by up to 68σ."""
    zf, mc, mr = [], [], []
    for ph, cal in cluttered_batch:
        zf.append(_z_focal(ph, cal))
        d = cal.principal_point - ph.K[:2, 2]
        mc.append(float(d @ np.linalg.solve(cal.covariance[1:3, 1:3], d)))
        w = Rotation.from_matrix(ph.R @ cal.R.T).as_rotvec()
        mr.append(float(w @ np.linalg.solve(cal.covariance[3:6, 3:6], w)))
    shares = {"f": float(np.mean(np.abs(zf) < Z95)), "c": float(np.mean(np.array(mc) < chi2.ppf(0.95, 2))),
              "R": float(np.mean(np.array(mr) < chi2.ppf(0.95, 3)))}
    for what, share in shares.items():
        assert COVERAGE_BAND[0] <= share <= COVERAGE_BAND[1], (what, shares)
    # Not yet caught (docs/accuracy.md): where a second building's edges lie within the lens
    # allowance of the consensus, it can keep them and reject one of the building's own; measured
    # 2 of these 400 beyond the bound (4.7σ and 15σ).
    assert np.sum(np.abs(zf) >= UNCERTAINTY_BOUND) <= 2, sorted(np.abs(zf))[-4:]


def test_the_command_records_and_says_the_rejected_segments(tmp_path) -> None:
    """`vebuild calibrate` writes each axis' rejected segments into the photo's calibration record
    (index, misfit, reason), keeps the residuals index for index with the marks, takes the RMS over
    the segments kept, says how many were rejected on the console, and `vebuild check` accepts it."""
    import json
    import subprocess
    import sys

    from vebuild.synthetic import random_scene, write_project

    rng = np.random.default_rng(4407)
    photos, markers = random_scene(rng, ("3vp", "3vp", "2vp", "3vp"))
    clutter = add_clutter(photos[0], rng, "slopes", "x", 2)
    path = write_project(tmp_path, photos, markers)
    r = subprocess.run([sys.executable, "-m", "vebuild", "calibrate", str(path)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    cam = json.loads(path.read_text())["calibration"]["cameras"][photos[0].id]
    vp = cam["vanishing_points"]["x"]
    assert [s["segment"] for s in vp["rejected"]] == clutter
    assert all(s["misfit_sigmas"] > 2 and s["reason"].startswith("off its vanishing point") for s in vp["rejected"])
    assert len(vp["residuals_px"]) == len(photos[0].segments["x"])
    kept = [v for k, v in enumerate(vp["residuals_px"]) if k not in clutter]
    assert vp["rms_px"] == pytest.approx(float(np.sqrt(np.mean(np.square(kept)))))
    assert f"x: {vp['rms_px']:.2f} px ({len(vp['residuals_px'])} segments, 2 rejected)" in r.stdout
    assert "2 of" in cam["mode_reason"] and "x segments rejected" in cam["mode_reason"]
    r = subprocess.run([sys.executable, "-m", "vebuild", "check", str(path)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr


def test_the_modelling_screen_draws_the_rejected_segments_grey(tmp_path) -> None:
    """The modelling screen's overlay of a calibrated photo draws the segments its calibration left
    out in grey, labelled with why, with a note saying what grey means; the others keep their
    axis' colour."""
    import subprocess
    import sys

    from vebuild.edit.overlay import AXIS_COLOURS, GREY
    from vebuild.edit.session import EditSession
    from vebuild.synthetic import random_scene, write_project

    rng = np.random.default_rng(4407)
    photos, markers = random_scene(rng, ("3vp", "3vp", "2vp", "3vp"))
    clutter = add_clutter(photos[0], rng, "slopes", "x", 2)
    path = write_project(tmp_path, photos, markers)
    r = subprocess.run([sys.executable, "-m", "vebuild", "calibrate", str(path)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    ov = EditSession.open(path).overlay(photos[0].id)
    lines = {ln.key: ln for ln in ov.of_kind("segment")[0]}
    for k in range(len(photos[0].segments["x"])):
        ln = lines[("x", k)]
        if k in clutter:
            assert ln.colour == GREY and ln.cross == AXIS_COLOURS["x"]
            assert f"x{k}: left out by the calibration: " in (ln.label or "") and "σ off the vanishing" in ln.label
        else:
            assert ln.colour in (AXIS_COLOURS["x"], ) or "outlier" in (ln.label or "")
    assert (f"{len(clutter)} grey crossed x segments: left out by the calibration: they do not meet the other x "
            "lines' vanishing point") in " ".join(ov.notes)
