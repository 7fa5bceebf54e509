"""Calibration of photographs as unkind as real ones: barrel distortion of a wide lens,
principal points a few per cent off centre, EXIF focal lengths a few per cent off, frontal and
corridor views, long edges marked as polylines.

The errors are drawn from the distributions the priors claim (principal point: 3 % of the longer
side per coordinate, calibration.priors.PRINCIPAL_POINT_SIGMA_REL; EXIF: 4 %, the σ calibration is
told), so the reported 95 % intervals must hold the truth 95 % of the time: not less (too narrow),
not more (too wide). With n photos the share's sampling 1σ is √(0.95 · 0.05 / n), 0.9 % at n = 600:
the band 93–97 % is ±2.2 of it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from vebuild.calibration.photo import DistortionPrior, FocalPrior, calibrate_photo
from vebuild.camera import Lens, distortion_displacement_px
from vebuild.errors import CalibrationError
from vebuild.synthetic import (
    CLICK_NOISE_PX,
    REAL_EXIF_FOCAL_ERROR_REL,
    SyntheticPhoto,
    add_segments,
    k1_for_corner_shift,
    random_camera,
    realistic_camera,
)

KINDS = ("3vp", "2vp", "frontal", "corridor")
N_COVERAGE = 600
#: |error| / reported 1σ that no photo may exceed (as in test_calibration: 4.5σ is a 1-in-10⁵ draw).
UNCERTAINTY_BOUND = 4.5
COVERAGE_BAND = (0.93, 0.97)
#: The principal point's interval is the 2D ellipse of its (2, 2) covariance: inside when the
#: squared Mahalanobis distance is below χ²₂'s 95 % quantile (5.99), not 1.96² per coordinate.
PP_QUANTILE = float(chi2.ppf(0.95, 2))


def _exif(ph: SyntheticPhoto) -> FocalPrior:
    assert ph.exif_focal_px is not None
    return FocalPrior(ph.exif_focal_px, ph.exif_focal_sigma_rel * ph.exif_focal_px, "exif")


def _calibrate(ph: SyntheticPhoto, **kw):
    return calibrate_photo(ph.segments, ph.width, ph.height, photo=ph.id, click_sigma_px=CLICK_NOISE_PX,
                           exif_focal=_exif(ph), **kw)


#: The tests that share `realistic_batch` run in one pytest-xdist worker (`--dist loadgroup`, pyproject's
#: addopts), so that it is computed once, not once per worker.
SHARES_REALISTIC_BATCH = pytest.mark.xdist_group("calibration_coverage.realistic_batch")


@pytest.fixture(scope="module")
def realistic_batch():
    """N_COVERAGE realistic photos, a quarter of each kind, with long edges marked as polylines
    of two middle points, and their calibrations."""
    rng = np.random.default_rng(20261122)
    out, refused = [], []
    for i in range(N_COVERAGE):
        ph = realistic_camera(rng, KINDS[i % len(KINDS)], photo_id=f"r{i}")
        add_segments(ph, rng, CLICK_NOISE_PX, middle_points=2)
        try:
            cal = _calibrate(ph)
        except CalibrationError as e:
            refused.append(str(e))
            continue
        out.append((ph, cal))
    return out, refused


@SHARES_REALISTIC_BATCH
def test_realistic_photos_are_never_refused(realistic_batch) -> None:
    batch, refused = realistic_batch
    # Every such photo has EXIF, so its segments, however weak, always give something. (What the
    # calibration costs per photo is `vebuild bench calibration`'s to say, not a test's.)
    assert refused == []


@SHARES_REALISTIC_BATCH
def test_focal_lengths_inside_their_95_percent_intervals(realistic_batch) -> None:
    batch, _ = realistic_batch
    z = np.array([(cal.f - ph.K[0, 0]) / cal.f_sigma for ph, cal in batch])
    share = float(np.mean(np.abs(z) < 1.959964))
    assert COVERAGE_BAND[0] <= share <= COVERAGE_BAND[1], share
    assert np.max(np.abs(z)) < UNCERTAINTY_BOUND
    for kind in KINDS:  # each kind holds its own (150 photos each: sampling 1σ 1.8 %)
        zk = np.array([(cal.f - ph.K[0, 0]) / cal.f_sigma for ph, cal in batch if ph.kind == kind])
        assert 0.89 <= np.mean(np.abs(zk) < 1.959964) <= 1.0, kind


@SHARES_REALISTIC_BATCH
def test_principal_points_inside_their_95_percent_ellipses(realistic_batch) -> None:
    batch, _ = realistic_batch
    m2 = []
    for ph, cal in batch:
        d = cal.principal_point - ph.K[:2, 2]
        m2.append(float(d @ np.linalg.solve(cal.covariance[1:3, 1:3], d)))
    share = float(np.mean(np.array(m2) < PP_QUANTILE))
    assert COVERAGE_BAND[0] <= share <= COVERAGE_BAND[1], share
    assert np.max(m2) < UNCERTAINTY_BOUND**2


@SHARES_REALISTIC_BATCH
def test_three_vanishing_points_give_f_within_one_percent(realistic_batch) -> None:
    """Tilted views: f from the segments within 1 % (median; measured 0.3–0.4 %), despite the
    distortion, the principal point off centre and EXIF 4 % off."""
    batch, _ = realistic_batch
    err = np.array([abs(cal.f - ph.K[0, 0]) / ph.K[0, 0] for ph, cal in batch if ph.kind == "3vp"])
    assert np.median(err) < 0.01
    assert np.percentile(err, 75) < 0.01


@SHARES_REALISTIC_BATCH
def test_frontal_and_corridor_views_take_f_from_exif_and_say_so(realistic_batch) -> None:
    batch, _ = realistic_batch
    pct = f"{100 * REAL_EXIF_FOCAL_ERROR_REL:.1f} %"
    for ph, cal in batch:
        if ph.kind in ("frontal", "corridor") and cal.mode == "1vp":
            assert cal.focal_source == "exif"
            assert cal.mode_reason.startswith(f"f from EXIF (1σ {pct}) combined with the vanishing points")
        assert "finite" not in cal.mode_reason
    modes = [cal.mode for ph, cal in batch if ph.kind in ("frontal", "corridor")]
    assert modes.count("1vp") >= 0.6 * len(modes)


@SHARES_REALISTIC_BATCH
def test_exif_is_a_cross_check_only_where_the_segments_are_surer(realistic_batch) -> None:
    """No silent blending: where EXIF is not combined the reason says so and how far it differs;
    where it is, the reason says both 1σ. EXIF the segments contradict beyond EXIF_DISAGREEMENT_SIGMAS
    is not combined either; with EXIF drawn from its stated 1σ that is a chance event (0.27 % of
    honest photos beyond 3σ; measured 1 of 600 here)."""
    from vebuild.calibration.photo import EXIF_DISAGREEMENT_SIGMAS

    batch, _ = realistic_batch
    combined = not_combined = contradicted = 0
    for _, cal in batch:
        r = cal.mode_reason
        if "the vanishing points contradicting it" in r:
            contradicted += 1
            assert cal.focal_source == "vanishing points" and cal.exif_check is not None
            assert not cal.exif_check.combined and cal.exif_check.sigmas > EXIF_DISAGREEMENT_SIGMAS
            assert "probably not this photo's focal length" in r
        elif "not combined" in r:
            not_combined += 1
            assert cal.focal_source == "vanishing points"
            assert "only a cross-check: EXIF's f = " in r and "differs from the vanishing points' by" in r
        else:
            combined += 1
            assert "combined with EXIF (1σ 4.0 %)" in r or r.startswith("f from EXIF (1σ 4.0 %) combined with")
    assert combined and not_combined
    assert contradicted <= 0.01 * len(batch)


def test_lens_distortion_recovered_from_polylines(rng: np.random.Generator) -> None:
    """Tilted views through a wide lens (corners moved 1–3 % of the half-diagonal), long edges marked
    with eight middle points: the corner displacement within 10 % of itself (median; measured
    8.6 %) and each k1 within its own 1σ (both ways: an RMS of error/σ near 1)."""
    rel, z = [], []
    for _ in range(40):
        ph = realistic_camera(rng, "3vp")
        add_segments(ph, rng, CLICK_NOISE_PX, per_axis=(5, 7), middle_points=8, polyline_min_length_rel=0.3,
                     min_length_rel=0.3)
        cal = _calibrate(ph)
        assert cal.k1_source == "segments" and cal.k1_sigma > 0
        true = distortion_displacement_px(ph.K, ph.width, ph.height, Lens(ph.k1))
        rel.append(abs(cal.distortion_corner_px - true) / true)
        z.append((cal.k1 - ph.k1) / cal.k1_sigma)
        assert cal.distortion_corner_px_sigma > 0
        assert abs(cal.distortion_corner_px - true) < UNCERTAINTY_BOUND * cal.distortion_corner_px_sigma
        assert f"lens distortion k1 = {cal.k1:+.4f}" in cal.mode_reason
    assert np.median(rel) < 0.10
    assert np.max(np.abs(z)) < UNCERTAINTY_BOUND
    assert 0.6 < np.sqrt(np.mean(np.square(z))) < 1.4


def test_without_middle_points_k1_is_a_prior_or_zero(rng: np.random.Generator) -> None:
    ph = random_camera(rng, "3vp")
    add_segments(ph, rng, CLICK_NOISE_PX)
    plain = _calibrate(ph)
    assert (plain.k1, plain.k1_sigma, plain.k1_source) == (0.0, 0.0, "none")
    assert plain.covariance_k1.shape == (7, 7)
    assert np.all(plain.covariance_k1[6] == 0) and np.all(plain.covariance_k1[:, 6] == 0)
    np.testing.assert_array_equal(plain.covariance, plain.covariance_k1[:6, :6])
    assert plain.distortion_corner_px == 0.0 and plain.distortion_corner_px_sigma == 0.0
    assert "no lens distortion modelled" in plain.mode_reason
    # A lens profile's k1 is held by its prior: straight two-point segments barely inform it, so
    # the result is the prior's, moved by little and no surer than it.
    k1 = k1_for_corner_shift(0.02, ph.K, ph.width, ph.height)
    prior = DistortionPrior(k1, 0.1 * abs(k1), "lens profile: Test 18mm")
    held = _calibrate(ph, distortion=prior)
    assert held.k1_source == "lens profile: Test 18mm"
    assert abs(held.k1 - k1) < 3 * prior.sigma and 0.5 * prior.sigma < held.k1_sigma <= prior.sigma * 1.0001
    assert "from lens profile: Test 18mm" in held.mode_reason


def test_polylines_with_the_profile_say_both(rng: np.random.Generator) -> None:
    ph = realistic_camera(rng, "3vp")
    add_segments(ph, rng, CLICK_NOISE_PX, middle_points=3)
    # A profile the lines agree with holds k1 there (vebuild/calibration/bending.py) ...
    prior = DistortionPrior(ph.k1, 0.2 * abs(ph.k1), "lens profile: Test 18mm")
    held = _calibrate(ph, distortion=prior)
    assert held.k1_source.startswith(f"k1 held at lens profile: Test 18mm's k1 {ph.k1:+.4f}: the lines bend no "
                                      "differently (LR test")
    assert held.k1 == ph.k1 and held.k1_sigma == 0.0
    # ... one they contradict (a pincushion where the lens is barrel) is combined with them.
    prior = DistortionPrior(-ph.k1, 0.2 * abs(ph.k1), "lens profile: Test 18mm")
    cal = _calibrate(ph, distortion=prior)
    assert cal.k1_source == "segments + lens profile: Test 18mm"
    assert "from the segments' straightness combined with lens profile: Test 18mm" in cal.mode_reason


def test_segments_and_two_point_polylines_are_the_same_marks(rng: np.random.Generator) -> None:
    """An (n, 4) array, a list of 4-number rows and a list of polylines of two points each are one
    input; the residuals reported are one per segment, the paper's for two points."""
    ph = random_camera(rng, "3vp")
    add_segments(ph, rng, CLICK_NOISE_PX)
    a = _calibrate(ph)
    as_lists = {k: [list(map(float, s)) for s in v] for k, v in ph.segments.items()}
    b = calibrate_photo(as_lists, ph.width, ph.height, click_sigma_px=CLICK_NOISE_PX, exif_focal=_exif(ph))
    np.testing.assert_allclose(a.K, b.K, rtol=1e-9)
    np.testing.assert_allclose(a.R, b.R, atol=1e-9)
    for axis, segs in ph.segments.items():
        assert a.segment_residuals_px[axis].shape == (len(segs),)


def test_a_near_infinite_vanishing_point_is_an_ordinary_case(rng: np.random.Generator) -> None:
    """Corridor views without EXIF: each is calibrated with its (wide) 1σ, or refused only for an
    undetermined focal length; no message speaks of vanishing points being 'finite'."""
    outcomes = {"calibrated": 0, "refused": 0}
    for _ in range(12):
        ph = random_camera(rng, "corridor", principal_point_sigma_rel=0.03)
        add_segments(ph, rng, CLICK_NOISE_PX)
        try:
            cal = calibrate_photo(ph.segments, ph.width, ph.height, photo="c", click_sigma_px=CLICK_NOISE_PX)
        except CalibrationError as e:
            outcomes["refused"] += 1
            assert "the focal length is not determined" in str(e) and "finite" not in str(e)
            continue
        outcomes["calibrated"] += 1
        assert abs(cal.f - ph.K[0, 0]) < UNCERTAINTY_BOUND * cal.f_sigma
        assert cal.mode_reason.startswith("f from the vanishing points")
    assert sum(outcomes.values()) == 12


def test_bench_cases_report_the_issue_figures() -> None:
    """`vebuild bench calibration`'s real-photograph cases carry their named figures."""
    from vebuild.bench.calibration import CASES, run_case

    assert set(CASES) == {"distortion", "off_centre_principal_point", "exif_errors", "frontal", "corridor",
                          "realistic"}
    fig = run_case("distortion", 8, 1)
    for key in ("focal_rel_error_median", "focal_rel_error_p90", "focal_coverage_95", "principal_point_coverage_95",
                "refusals", "distortion_corner_px_error_median"):
        assert key in fig and key in fig["goals"] or key == "distortion_corner_px_error_median"
    assert fig["refusals"] == 0 and fig["distortion_corner_px_error_median"] > 0
    assert run_case("exif_errors", 3, 1)["distortion_corner_px_error_median"] is None


def test_an_exif_focal_length_far_off_is_called_so(rng: np.random.Generator) -> None:
    """EXIF 20 % off (a crop, or a zoom step EXIF does not record) on a tilted view: the segments
    are surer, so EXIF is not combined, and the cross-check says it is probably wrong."""
    ph = random_camera(rng, "3vp")
    add_segments(ph, rng, CLICK_NOISE_PX)
    exif = FocalPrior(1.2 * ph.K[0, 0], 0.04 * 1.2 * ph.K[0, 0], "exif")
    cal = calibrate_photo(ph.segments, ph.width, ph.height, click_sigma_px=CLICK_NOISE_PX, exif_focal=exif)
    assert cal.focal_source == "vanishing points"
    assert abs(cal.f - ph.K[0, 0]) < UNCERTAINTY_BOUND * cal.f_sigma
    assert "not combined" in cal.mode_reason and "probably not this photo's focal length" in cal.mode_reason
    # Given by the user instead, it is combined (a user's value is always used), and EXIF is unused.
    user = calibrate_photo(ph.segments, ph.width, ph.height, click_sigma_px=CLICK_NOISE_PX, exif_focal=exif,
                           focal=FocalPrior(ph.K[0, 0], 0.01 * ph.K[0, 0], "user"))
    assert "combined with the user's focal length (1σ 1.0 %)" in user.mode_reason or \
        "f from the user's focal length (1σ 1.0 %)" in user.mode_reason
    assert "EXIF not used" in user.mode_reason


def test_the_modelling_screen_keeps_and_draws_polylines(tmp_path, rng: np.random.Generator) -> None:
    """A polyline added in the modelling screen is stored whole; dragging one of its ends keeps its
    middle points; the overlay draws its path; its vanishing point is fitted from its ends."""
    from vebuild.edit.session import EditSession
    from vebuild.synthetic import random_scene, write_project

    photos, markers = random_scene(rng, ("3vp", "3vp", "2vp"))
    s = EditSession.open(write_project(tmp_path, photos, markers), autosave=False)
    seg = np.asarray(photos[0].segments["x"][0], float)
    mid = (seg[:2] + seg[2:]) / 2
    i = s.add_polyline("p1", "x", [seg[:2], mid, seg[2:]])
    s.move_segment("p1", "x", i, [*seg[:2], *(seg[2:] + 1.0)])
    stored = s.photo("p1")["vanishing_segments"]["x"][i]
    assert len(stored) == 6 and stored[2:4] == pytest.approx(mid) and stored[4:] == pytest.approx(seg[2:] + 1.0)
    vs = s.vanishing("p1", "x")
    assert vs.segments.shape == (len(photos[0].segments["x"]) + 1, 4) and len(vs.polylines[i]) == 3
    assert vs.point is not None
    paths, points = s.overlay("p1").of_kind("segment-path")
    assert len(paths) == 2 and len(s.overlay("p1").of_kind("segment-point")[1]) == 1
