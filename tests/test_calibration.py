"""Calibration from vanishing points (paper §2) on seeded synthetic cameras with known answers.

Tolerances are the accuracy claims of tests/claims.py for 0.7 px click noise and EXIF focal
lengths off by 2 % (each with its measurement there). They are asserted on the median over a
batch of random cameras of each kind; every single camera must in addition lie
within UNCERTAINTY_BOUND of its own reported 1σ, so a camera that is less accurate says so.
"""

from __future__ import annotations

import numpy as np
import pytest
from claims import FOCAL_TOL_REL, FOCAL_TOL_REL_2VP, POSITION_TOL_REL, ROTATION_TOL_DEG, ROTATION_TOL_DEG_2VP
from scipy.stats import chi2

from vebuild.calibration.photo import FocalPrior, calibrate_photo, closed_form_calibration
from vebuild.calibration.positions import PhotoInput, ReferenceDistance, place_cameras
from vebuild.calibration.start import MIN_INTERSECTION_ANGLE_DEG
from vebuild.calibration.vanishing import fit_vanishing_point
from vebuild.camera import log_so3
from vebuild.errors import CalibrationError
from vebuild.synthetic import (
    CLICK_NOISE_PX,
    EXIF_FOCAL_ERROR_REL,
    ROOM,
    add_segments,
    project_points,
    projection_matrix,
    random_camera,
    random_scene,
    rotation,
    scale_reference,
)

#: |error| / reported 1σ that no camera may exceed: 4.5σ happens by chance about once in 10⁵
#: draws of a Gaussian, so a larger ratio means the reported uncertainty is wrong.
UNCERTAINTY_BOUND = 4.5
#: RMS of error / reported 1σ over a batch: 1 for honest uncertainties. The band allows for the
#: sampling spread of an RMS over ~100 values and for the floor on the variance factor, which
#: errs on the side of reporting too much uncertainty.
Z_RMS_BAND = (0.5, 1.3)
N_PER_KIND = 40


def _exif(f_exif: float) -> FocalPrior:
    """The EXIF focal length (off the truth by EXIF_FOCAL_ERROR_REL, 1σ) with that 1σ."""
    return FocalPrior(f_exif, EXIF_FOCAL_ERROR_REL * f_exif, "exif")


#: random_camera's principal points lie off centre by 1 % of the width (1σ): the claims of
#: tests/claims.py were measured with the prior matching that spread. Real cameras' wider spread and
#: the default 3 % prior are tested in tests/test_calibration_coverage.py.
PP_SIGMA_REL = 0.01


def _calibrate_batch(kind: str, rng: np.random.Generator):
    out = []
    for _ in range(N_PER_KIND):
        cam = random_camera(rng, kind)
        add_segments(cam, rng, CLICK_NOISE_PX)
        exif = _exif(cam.exif_focal_px)
        cal = calibrate_photo(cam.segments, cam.width, cam.height, click_sigma_px=CLICK_NOISE_PX, exif_focal=exif,
                              principal_point_sigma_rel=PP_SIGMA_REL)
        out.append((cam, cal))
    return out


@pytest.mark.parametrize("kind", ["3vp", "2vp", "1vp"])
def test_intrinsics_and_rotation_accuracy(kind: str, rng: np.random.Generator) -> None:
    batch = _calibrate_batch(kind, rng)
    f_err = np.array([(cal.f - cam.K[0, 0]) / cam.K[0, 0] for cam, cal in batch])
    w_err = np.array([log_so3(cam.R @ cal.R.T) for cam, cal in batch])
    rot_deg = np.degrees(np.linalg.norm(w_err, axis=1))
    if kind == "1vp":
        # f is EXIF's, off the truth by EXIF_FOCAL_ERROR_REL (1σ): the median |error| of 40 such
        # draws is 0.674σ with a spread of 0.124σ (1 / (2 density · √40)); the band is ±3.5 of that
        # (measured over 8 seeds: 0.52–0.69σ).
        assert 0.24 * EXIF_FOCAL_ERROR_REL < np.median(np.abs(f_err)) < 1.11 * EXIF_FOCAL_ERROR_REL
    else:
        assert np.median(np.abs(f_err)) < (FOCAL_TOL_REL_2VP if kind == "2vp" else FOCAL_TOL_REL)
    assert np.median(rot_deg) < (ROTATION_TOL_DEG_2VP if kind == "2vp" else ROTATION_TOL_DEG)
    z_f = np.array([(cal.f - cam.K[0, 0]) / cal.f_sigma for cam, cal in batch])
    z_w = np.concatenate([w / cal.rotation_sigma_rad for w, (_, cal) in zip(w_err, batch, strict=True)])
    assert np.max(np.abs(z_f)) < UNCERTAINTY_BOUND
    assert np.max(np.abs(z_w)) < UNCERTAINTY_BOUND
    assert Z_RMS_BAND[0] < np.sqrt(np.mean(z_w**2)) < Z_RMS_BAND[1]
    assert Z_RMS_BAND[0] < np.sqrt(np.mean(z_f**2)) < Z_RMS_BAND[1]


def test_mode_follows_the_geometry(rng: np.random.Generator) -> None:
    """The mode follows what the segments determine, not the kind of view: each photo's mode must
    agree with the 1σ its reason states, and the kinds fall mostly where their geometry puts them."""
    modes = {kind: [cal.mode for _, cal in _calibrate_batch(kind, rng)] for kind in ("3vp", "2vp", "1vp")}
    # A tilted camera mostly gets f and c from its vanishing points (a weak third one cedes c to
    # the prior, a weak view cedes f to EXIF's 2 %: measured 27, 12 and 1 of 40).
    assert modes["3vp"].count("3vp") >= N_PER_KIND // 2
    assert modes["3vp"].count("1vp") <= N_PER_KIND // 10
    # A level camera: verticals at infinity, so c from its prior (measured 30 2vp, 10 1vp where EXIF's
    # 2 % is surer than the two vanishing points with c uncertain).
    assert modes["2vp"].count("3vp") <= N_PER_KIND // 10 and modes["2vp"].count("2vp") >= 0.6 * N_PER_KIND
    # A frontal view: f must come from EXIF.
    assert modes["1vp"].count("1vp") >= 0.9 * N_PER_KIND


def test_frontal_view_uses_exif_and_says_so(rng: np.random.Generator) -> None:
    cam = random_camera(rng, "1vp")
    add_segments(cam, rng, CLICK_NOISE_PX)
    f, f_exif = cam.K[0, 0], cam.exif_focal_px
    cal = calibrate_photo(cam.segments, cam.width, cam.height, click_sigma_px=CLICK_NOISE_PX,
                          exif_focal=_exif(f_exif))
    assert cal.mode == "1vp" and cal.focal_source == "exif"
    assert "EXIF" in cal.mode_reason or "exif" in cal.mode_reason
    # The focal length is EXIF's, not invented: one finite vanishing point barely constrains f, so
    # the error against the truth is EXIF's own, moved by the data a small share of EXIF's 1σ, and
    # the reported 1σ is EXIF's or a little more (measured over 30 seeds: moved at most 0.34σ; 1σ
    # 0.99–1.41 of EXIF's, the fit's variance factor).
    assert abs(cal.f - f_exif) < 0.5 * EXIF_FOCAL_ERROR_REL * f
    assert abs(cal.f - f) < UNCERTAINTY_BOUND * cal.f_sigma
    assert 0.9 * EXIF_FOCAL_ERROR_REL * f_exif < cal.f_sigma < 1.6 * EXIF_FOCAL_ERROR_REL * f_exif


def test_principal_point_prior_beats_both_pure_modes(rng: np.random.Generator) -> None:
    """Orthocentre alone (paper) wanders; the prior alone ignores the data; the joint fit is better than either."""
    errs_joint, errs_ortho, errs_centre = [], [], []
    for _ in range(N_PER_KIND):
        cam = random_camera(rng, "3vp")
        add_segments(cam, rng, CLICK_NOISE_PX)
        cal = calibrate_photo(cam.segments, cam.width, cam.height, click_sigma_px=CLICK_NOISE_PX)
        K_paper, _ = closed_form_calibration(cam.segments, cam.width, cam.height)
        c_true = cam.K[:2, 2]
        errs_joint.append(np.linalg.norm(cal.principal_point - c_true))
        errs_ortho.append(np.linalg.norm(K_paper[:2, 2] - c_true))
        errs_centre.append(np.linalg.norm(np.array([cam.width, cam.height]) / 2 - c_true))
    assert np.median(errs_joint) < np.median(errs_ortho)
    assert np.median(errs_joint) < np.median(errs_centre)


def test_vanishing_point_fit_recovers_a_known_point_and_reports_residuals(rng: np.random.Generator) -> None:
    """Over 30 draws of 5 segments toward a point 1.5 image widths away, the fitted point's error
    and the residuals are what 0.7 px of click noise predicts, both ways (too good is wrong too)."""
    v = np.array([2400.0, 350.0])
    n_draws, n_seg = 30, 5
    mahalanobis2, residual2 = [], []
    for _ in range(n_draws):
        ends = []
        for _ in range(n_seg):
            a = rng.uniform([100, 100], [1500, 1100])
            ends.append(np.r_[a, a + 0.4 * (v - a)])  # v = a + 2.5 (b − a)
        ends = np.array(ends)
        fit = fit_vanishing_point(ends + rng.normal(0, CLICK_NOISE_PX, ends.shape), 1600, 1200)
        p = fit.finite_point()
        assert p is not None and fit.residuals_px.shape == (n_seg,)
        # Predicted covariance: a segment's line, extended to the point (t = 2.5 of its length from
        # a), moves sideways by σ √((1 − t)² + t²); the point is where the lines meet (2 unknowns).
        info = np.zeros((2, 2))
        for a, b in zip(ends[:, :2], ends[:, 2:], strict=True):
            d = b - a
            n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
            t = (v - a) @ d / (d @ d)
            info += np.outer(n, n) / (CLICK_NOISE_PX**2 * ((1 - t) ** 2 + t**2))
        e = p - v
        mahalanobis2.append(e @ info @ e)
        # A residual is p1's distance to the line midpoint–point: σ/√2 per segment, and the fitted
        # point takes 2 of the 5 degrees of freedom.
        residual2.append(np.sum(fit.residuals_px**2) / (CLICK_NOISE_PX**2 / 2))
    # Sums of chi-squares: chi²(2·30) and chi²(3·30); each band holds 99.99 % of its distribution
    # (measured over 400 draws: the point's error follows chi²(2), KS p = 0.36; the residuals
    # chi²(3), KS p = 0.10). A stated tolerance of 32 px or 2.8 px RMS would hide a 10× error.
    assert chi2(2 * n_draws).ppf(1e-4) < np.sum(mahalanobis2) < chi2(2 * n_draws).ppf(1 - 1e-4)
    assert chi2(3 * n_draws).ppf(1e-4) < np.sum(residual2) < chi2(3 * n_draws).ppf(1 - 1e-4)


def test_parallel_segments_give_a_point_at_infinity() -> None:
    segs = np.array([[100.0, 100.0, 900.0, 140.0], [120.0, 700.0, 920.0, 740.0], [300, 400, 700, 420]])
    fit = fit_vanishing_point(segs, 1600, 1200)
    assert fit.finite_point() is None or np.linalg.norm(fit.finite_point()) > 1e6
    d = fit.point[:2] / np.linalg.norm(fit.point[:2])
    assert abs(abs(d @ np.array([800.0, 40.0]) / np.hypot(800, 40)) - 1) < 1e-9
    assert fit.rms_px < 1e-6


def test_segment_direction_fixes_the_rotation_signs(rng: np.random.Generator) -> None:
    cam = random_camera(rng, "2vp")
    add_segments(cam, rng, CLICK_NOISE_PX)
    segs = {a: cam.segments[a] for a in ("x", "y")}
    R1 = calibrate_photo(segs, cam.width, cam.height, click_sigma_px=CLICK_NOISE_PX).R
    flipped = {"x": segs["x"][:, [2, 3, 0, 1]], "y": segs["y"][:, [2, 3, 0, 1]]}
    R2 = calibrate_photo(flipped, cam.width, cam.height, click_sigma_px=CLICK_NOISE_PX).R
    # A wrong sign puts the camera 180° off; with two axes and the principal point a few tens of
    # pixels from the centre, the right answer is within a couple of degrees (Δc / f).
    assert np.degrees(np.linalg.norm(log_so3(cam.R @ R1.T))) < 5.0
    # Drawing x and y backwards means +x and +y are the other way: their columns flip, z = x × y not.
    assert R2[:, :2] == pytest.approx(-R1[:, :2], abs=1e-6)
    assert R2[:, 2] == pytest.approx(R1[:, 2], abs=1e-6)
    assert np.linalg.det(R2) == pytest.approx(1.0)
    # x alone backwards turns z = x × y down the photo: the floor would be overhead, and it is refused.
    with pytest.raises(CalibrationError, match=r"^photo 'photo': its world would be upside down, the floor overhead: "
                       r"z, which is x × y, points down the photo: reverse the direction of the x or the y segments$"):
        calibrate_photo({"x": flipped["x"], "y": segs["y"]}, cam.width, cam.height, click_sigma_px=CLICK_NOISE_PX)


def _place_scene(rng: np.random.Generator, kinds=("3vp", "3vp", "2vp", "1vp")):
    photos, markers = random_scene(rng, kinds, noise_px=CLICK_NOISE_PX)
    inputs = []
    for ph in photos:
        cal = calibrate_photo(ph.segments, ph.width, ph.height, photo=ph.id, click_sigma_px=CLICK_NOISE_PX,
                              exif_focal=_exif(ph.exif_focal_px))
        inputs.append(PhotoInput(ph.id, cal.K, cal.R, cal.covariance, ph.markers))
    a, b, d = scale_reference(photos, markers)
    placement = place_cameras(inputs, origin="O", distances=[ReferenceDistance(a, b, d, 0.002)],
                              click_sigma_px=CLICK_NOISE_PX)
    return photos, markers, placement


def test_camera_positions_metric_and_honest(rng: np.random.Generator) -> None:
    diag = float(np.linalg.norm(ROOM))
    errs, zs, errs_by_kind = [], [], {}
    for _ in range(12):
        photos, markers, placement = _place_scene(rng)
        for ph in photos:
            cam = placement.cameras[ph.id]
            e = cam.C - ph.C
            sig = np.sqrt(np.diag(cam.covariance)[6:9])
            errs.append(np.linalg.norm(e))
            errs_by_kind.setdefault(ph.kind, []).append(np.linalg.norm(e))
            zs.append(e / sig)
            assert np.all(np.abs(e / sig) < UNCERTAINTY_BOUND)
        for n, (x, cov) in placement.markers.items():
            if n != "O":
                assert np.all(np.abs(x - markers[n]) / np.sqrt(np.diag(cov)) < UNCERTAINTY_BOUND)
    for kind, e in errs_by_kind.items():
        assert np.median(e) < POSITION_TOL_REL * diag, kind
    assert Z_RMS_BAND[0] < np.sqrt(np.mean(np.square(zs))) < Z_RMS_BAND[1]


def test_photo_without_origin_is_placed_from_markers(rng: np.random.Generator) -> None:
    photos, markers, placement = _place_scene(rng, ("3vp", "3vp", "1vp"))
    frontal = photos[2]
    assert frontal.id in placement.cameras
    cam = placement.cameras[frontal.id]
    e = cam.C - frontal.C
    sigma = np.sqrt(np.diag(cam.covariance)[6:9])
    # A frontal photo's f is EXIF's (1σ EXIF_FOCAL_ERROR_REL) and it is placed from markers only,
    # so how well it is placed depends on what it sees (measured over 29 seeds: median 0.2 % of the
    # room's diagonal, 2.6 % at the 95th percentile): it is held to its own reported 1σ, per axis
    # (measured: at most 2.2σ), rather than to a multiple of the 3-photo claim.
    assert np.all(np.abs(e / sigma) < UNCERTAINTY_BOUND)


def _look(C: np.ndarray, target: np.ndarray) -> np.ndarray:
    d = target - C
    return rotation(float(np.arctan2(d[1], d[0])), float(np.arctan2(d[2], np.hypot(d[0], d[1]))), 0.0)


def test_origin_seen_by_two_photos_in_line_with_it_is_placed_from_another_start() -> None:
    """Only photos A and B see the origin marker O, from almost the same line through it (their
    rays to O meet at 0.5°, under MIN_INTERSECTION_ANGLE_DEG), and C and D see the markers near it
    but not O. The construction from O places A and then nothing (B's line to O runs along the
    baseline; C and D see no placed marker), which used to fail the whole placement with "cannot be
    placed"; started from another marker it places all four, and the refinement puts every camera
    within its reported σ of the truth (0.3 px clicks)."""
    rng = np.random.default_rng(11)
    K = np.array([[1400.0, 0, 800], [0, 1400.0, 600], [0, 0, 1]])
    markers = {"O": np.zeros(3), "M1": np.array([0.5, 0.0, 0.8]), "M2": np.array([0.0, 1.0, 0.4]),
               "M3": np.array([0.9, 0.0, 1.5]), "M4": np.array([0.0, 0.6, 1.3]), "M5": np.array([0.0, 1.8, 1.0]),
               "M6": np.array([1.6, 0.0, 0.6])}
    A = np.array([4.0, 3.2, 1.6])
    turn = np.radians(0.5)
    Rz = np.array([[np.cos(turn), -np.sin(turn), 0], [np.sin(turn), np.cos(turn), 0], [0, 0, 1]])
    centres = {"A": A, "B": Rz @ (0.6 * A), "C": np.array([3.0, 1.2, 1.4]), "D": np.array([1.5, 3.0, 1.2])}
    target = np.array([0.4, 0.5, 0.8])
    inputs, truth = [], {}
    for pid, C in centres.items():
        R = _look(C, target)
        uv, z = project_points(projection_matrix(K, R, C), np.array(list(markers.values())))
        seen = {n: p + rng.normal(0.0, 0.3, 2) for n, p, d in zip(markers, uv, z, strict=True)
                if d > 0 and 0 <= p[0] <= 1600 and 0 <= p[1] <= 1200 and (n != "O" or pid in "AB")}
        assert len(seen) >= 5 and ("O" in seen) == (pid in "AB"), (pid, sorted(seen))
        inputs.append(PhotoInput(pid, K, R, np.diag([1.0, 1.0, 1.0, 1e-8, 1e-8, 1e-8]), seen))
        truth[pid] = C
    rays = [np.linalg.solve(K, np.r_[p.markers["O"], 1.0]) for p in inputs[:2]]
    rays = [p.R.T @ r / np.linalg.norm(r) for p, r in zip(inputs[:2], rays, strict=True)]
    assert np.degrees(np.arccos(abs(rays[0] @ rays[1]))) < MIN_INTERSECTION_ANGLE_DEG
    placement = place_cameras(inputs, origin="O", distances=[ReferenceDistance("M1", "M6", 1.1, 0.001)],
                              click_sigma_px=0.3)
    for pid, C in truth.items():
        cam = placement.cameras[pid]
        sigma = np.sqrt(np.diag(cam.covariance)[6:9])
        assert np.all(np.abs(cam.C - C) / sigma < UNCERTAINTY_BOUND), (pid, cam.C, C, sigma)


def test_check_distance_is_not_used_but_reported(rng: np.random.Generator) -> None:
    photos, markers, _ = _place_scene(rng)
    inputs = []
    for ph in photos:
        cal = calibrate_photo(ph.segments, ph.width, ph.height, photo=ph.id, click_sigma_px=CLICK_NOISE_PX,
                              exif_focal=_exif(ph.exif_focal_px))
        inputs.append(PhotoInput(ph.id, cal.K, cal.R, cal.covariance, ph.markers))
    a, b, d = scale_reference(photos, markers)
    others = [n for n in markers if n not in (a, b)]
    true_check = float(np.linalg.norm(markers[others[0]] - markers[others[1]]))
    scale = ReferenceDistance(a, b, d, 0.002)
    wrong_check = ReferenceDistance(others[0], others[1], 2 * true_check, 0.002, "check")
    p1 = place_cameras(inputs, origin="O", distances=[scale], click_sigma_px=CLICK_NOISE_PX)
    p2 = place_cameras(inputs, origin="O", distances=[scale, wrong_check], click_sigma_px=CLICK_NOISE_PX)
    # A check distance, however wrong, does not move anything...
    for pid in p1.cameras:
        assert p2.cameras[pid].C == pytest.approx(p1.cameras[pid].C, abs=1e-9)
    # ...and is reported as measured against known, the measurement agreeing with the truth.
    m = next(m for m in p2.distances if m.reference.role == "check")
    assert abs(m.measured - true_check) < UNCERTAINTY_BOUND * m.measured_sigma


@pytest.mark.parametrize("exif_error, warned", [(0.04, False), (0.15, True)])
def test_the_exif_cross_check_weighs_exif_by_its_honest_sigma(tmp_path, exif_error, warned):
    """EXIF 4 % off is 1.3σ of its 3 % prior: no warning; 15 % off (a crop, a digital zoom) is
    beyond 3σ of the estimate's and EXIF's 1σ together: named. The record holds both figures."""
    from vebuild.actions.calibrate import calibrate_project
    from vebuild.project import load_project, save_project
    from vebuild.synthetic import random_scene, write_project

    photos, markers = random_scene(np.random.default_rng(5), ("3vp", "3vp", "3vp"))
    path = write_project(tmp_path, photos, markers)
    project = load_project(path)
    p1, true_f = project.data["photos"][0], photos[0].K[0, 0]
    diag = np.hypot(p1["width"], p1["height"])
    p1["exif"] = {"focal_length_35mm": float(true_f * (1 + exif_error) * np.hypot(36.0, 24.0) / diag)}
    save_project(project)
    result = calibrate_project(load_project(path))
    check = result["cameras"]["p1"]["exif_focal_check"]
    # EXIF relative to the vanishing points' estimate (the one sign convention): + where EXIF is longer.
    assert check["difference_rel"] == pytest.approx(exif_error, abs=0.01)
    assert 0.03 < check["sigma_rel"] < 0.06 and "35 mm" in check["source"]
    named = [w for w in result["warnings"] if w.startswith("photo 'p1': EXIF's focal length")]
    assert bool(named) == warned
    if warned:
        assert f"is {100 * check['difference_rel']:+.1f} % from the vanishing points'" in named[0]
        assert "beyond the 3σ limit" in named[0] and "check the segments, or the photo was cropped" in named[0]
