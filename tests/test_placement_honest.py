"""The joint placement honest where a photo's vanishing-point calibration is wrong and overconfident
(what real photos' clutter gives), and where a camera's covariance cannot be computed."""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.calibration.positions import PhotoInput, ReferenceDistance, place_cameras
from vebuild.camera import exp_so3
from vebuild.errors import CalibrationError
from vebuild.synthetic import random_scene, scale_reference

CLICK = 1.0


def _scene(seed: int):
    rng = np.random.default_rng(seed)
    photos, markers = random_scene(rng, ("3vp", "3vp", "2vp", "3vp"), noise_px=CLICK, n_markers=16)
    a, b, d = scale_reference(photos, markers)
    return photos, [ReferenceDistance(a, b, d, 0.002)]


def _prior(sig_f: float, sig_c: float, sig_w: float, sig_k1: float) -> np.ndarray:
    return np.diag([sig_f**2, sig_c**2, sig_c**2, sig_w**2, sig_w**2, sig_w**2, sig_k1**2])


@pytest.mark.parametrize("seed", [3, 11])
def test_wrong_overconfident_calibration_is_said_and_widened(seed: int) -> None:
    """One photo's vanishing points say f 18 % long, the camera turned 2°, with a 0.5 % σ (the
    clutter that real photos' detection groups into an axis): its markers contradict that. The
    placement must say so naming the photo, and report neither a confident wrong f nor a k1 no
    lens has (on main: no warning, k1 and f pulled with a σ as if the prior had held)."""
    photos, refs = _scene(seed)
    bad = photos[1]
    inputs = []
    for ph in photos:
        K, R = ph.K.copy(), ph.R.copy()
        cov = _prior(0.005 * ph.K[0, 0], 5.0, 0.002, 0.01)
        if ph is bad:
            K[0, 0] = K[1, 1] = 1.18 * ph.K[0, 0]
            R = exp_so3(np.radians([2.0, -1.0, 0.5])) @ ph.R
        inputs.append(PhotoInput(ph.id, K, R, cov, ph.markers, 0.0, 0.01,
                                 corner_px=0.5 * float(np.hypot(ph.width, ph.height))))
    placement = place_cameras(inputs, origin="O", distances=refs, click_sigma_px=CLICK)
    said = [w for w in placement.warnings if f"photo '{bad.id}'" in w]
    assert said, placement.warnings
    cam = placement.cameras[bad.id]
    f_true = bad.K[0, 0]
    # Honest: the true f and k1 (0) within 3σ of what is reported (a 99.7 % two-sided interval).
    assert abs(cam.K[0, 0] - f_true) <= 3.0 * np.sqrt(cam.covariance[0, 0])
    assert abs(cam.k1) <= 3.0 * cam.k1_sigma


def test_honest_calibrations_raise_no_contradiction() -> None:
    """Priors that hold the truth within their σ: no photo is said to contradict its markers, and
    no σ is widened beyond the solve's own (the test's false-alarm rate is 1 in 1,000 per photo)."""
    photos, refs = _scene(5)
    rng = np.random.default_rng(7)
    inputs = []
    for ph in photos:
        sig_f = 0.01 * ph.K[0, 0]
        K = ph.K.copy()
        K[0, 0] = K[1, 1] = ph.K[0, 0] + rng.normal(0.0, sig_f)
        R = exp_so3(rng.normal(0.0, 0.002, 3)) @ ph.R
        inputs.append(PhotoInput(ph.id, K, R, _prior(sig_f, 5.0, 0.002, 0.01), ph.markers, 0.0, 0.01,
                                 corner_px=0.5 * float(np.hypot(ph.width, ph.height))))
    placement = place_cameras(inputs, origin="O", distances=refs, click_sigma_px=CLICK)
    assert not [w for w in placement.warnings if "contradict" in w]


def test_camera_the_marks_cannot_determine_is_refused_by_name() -> None:
    """A photo whose vanishing points fix nothing (σ of f and rotation astronomically large) and
    whose two markers cannot fix its focal length, rotation and position: its covariance is not
    finite. It must be refused by name (calibrate then leaves it out), not returned with an
    infinite σ (on main: placed, its σ written as null)."""
    photos, refs = _scene(3)
    weak = photos[3]
    shared = [n for n in weak.markers if n != "O" and n in photos[0].markers and n in photos[1].markers][:1]
    inputs = []
    for ph in photos:
        if ph is weak:
            marks = {n: ph.markers[n] for n in ["O", *shared]}
            cov = np.diag([1e24, 1e24, 1e24, 1e12, 1e12, 1e12])
        else:
            marks, cov = ph.markers, _prior(0.01 * ph.K[0, 0], 5.0, 0.002, 0.01)[:6, :6]
        inputs.append(PhotoInput(ph.id, ph.K, ph.R, cov, marks))
    with pytest.raises(CalibrationError) as e:
        place_cameras(inputs, origin="O", distances=refs, click_sigma_px=CLICK)
    assert e.value.photo == weak.id
    assert "cannot determine" in e.value.detail and "mark more" in e.value.detail
