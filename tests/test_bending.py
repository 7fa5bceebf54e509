"""Lens distortion only where the lines ask for it (vebuild/calibration/bending.py).

Generated photos reproduce the failure: photos already undistorted by their authors (true k1 = 0),
3072 × 2048, every marked edge a polyline of four points as ``vebuild detect`` writes them, 1 px
noise. Before the test every such photo got k1 estimated, a few σ from zero now and then, moving
its corners by 10–20 px; now k1 is held at 0 unless a likelihood-ratio test at the stated level
says the lines bend, and the record, the mode reason and the console say which, with the test's
figures.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
from scipy.stats import binom

from vebuild.calibration.bending import DISTORTION_TEST_LEVEL
from vebuild.calibration.photo import FocalPrior, calibrate_photo
from vebuild.errors import CalibrationError
from vebuild.synthetic import (
    SyntheticPhoto,
    add_segments,
    k1_for_corner_shift,
    random_scene,
    realistic_camera,
    write_project,
)

WIDTH, HEIGHT = 3072, 2048
#: Click (detection) noise of every point, px.
NOISE_PX = 1.0
KINDS = ("3vp", "2vp", "frontal", "corridor")
#: Photos over which the false-positive rate is counted: with the level 5 % the count of photos
#: whose k1 is estimated is Binomial(N, 0.05); the band is its 0.05 %–99.95 % quantiles (a test
#: that fails once in a thousand runs of a correct test, not more).
N_FALSE_POSITIVE = 200
BAND_QUANTILE = 0.0005


def _photo(rng: np.random.Generator, i: int, corner_rel: float = 0.0) -> SyntheticPhoto:
    """A realistic camera (principal point 3 % off, EXIF 4 % off) with a lens that moves the corners
    by corner_rel of the half-diagonal (0: undistorted), every edge a four-point polyline."""
    ph = realistic_camera(rng, KINDS[i % len(KINDS)], WIDTH, HEIGHT, photo_id=f"p{i}", distortion=False)
    if corner_rel:
        ph.k1 = k1_for_corner_shift(corner_rel, ph.K, WIDTH, HEIGHT)
    add_segments(ph, rng, NOISE_PX, per_axis=(5, 10), min_length_rel=0.1, middle_points=2,
                 polyline_min_length_rel=0.0)
    return ph


def _calibrate(ph: SyntheticPhoto):
    assert ph.exif_focal_px is not None
    exif = FocalPrior(ph.exif_focal_px, ph.exif_focal_sigma_rel * ph.exif_focal_px, "exif")
    return calibrate_photo(ph.segments, ph.width, ph.height, photo=ph.id, click_sigma_px=NOISE_PX, exif_focal=exif)


def _batch(seed: int, n: int, corner_rel: float = 0.0) -> list:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        ph = _photo(rng, i, corner_rel)
        try:
            out.append((ph, _calibrate(ph)))
        except CalibrationError:  # a frontal view whose lines and EXIF leave f undetermined
            continue
    return out


def test_undistorted_photos_hold_k1_at_zero_and_say_so() -> None:
    batch = _batch(20261207, 12)
    held = [cal for _, cal in batch if not cal.distortion_test.bends]
    assert len(held) >= 0.75 * len(batch)
    for cal in held:
        assert (cal.k1, cal.k1_sigma) == (0.0, 0.0)
        assert cal.distortion_corner_px == 0.0
        assert np.all(cal.covariance_k1[6] == 0) and np.all(cal.covariance_k1[:, 6] == 0)
        t = cal.distortion_test
        assert cal.k1_source.startswith("k1 held at 0: the lines do not bend (LR test: Δχ² = ")
        assert f"Δχ² = {t.statistic:.2f}, p = {t.p_value:.2g}, level 0.05" in cal.k1_source
        assert "lens distortion k1 held at 0: the lines do not bend (LR test" in cal.mode_reason
        # The camera's covariance still carries what a k1 the test cannot see would do to it.
        assert cal.principal_point_sigma.min() > 0 and cal.f_sigma > 0


def test_barrel_lenses_are_estimated_and_within_their_interval() -> None:
    """A barrel lens moving the corners by 2 % of the half-diagonal (18 px here): every photo's lines
    bend, k1 is estimated from them, within 3σ of the truth, and the mode reason says why."""
    for ph, cal in _batch(7, 12, corner_rel=0.02):
        assert cal.distortion_test.bends and cal.distortion_test.p_value < DISTORTION_TEST_LEVEL
        assert cal.k1_source == "segments" and cal.k1_sigma > 0
        assert abs(cal.k1 - ph.k1) < 3 * cal.k1_sigma
        assert "; estimated: the lines bend (LR test: Δχ² = " in cal.mode_reason


def test_false_positive_rate_is_the_stated_level() -> None:
    """Over N_FALSE_POSITIVE undistorted photos the share whose k1 is estimated is the test's level
    (5 %) within the binomial band (2–21 of 200); it was every photo before the test (measured here:
    10 of 200)."""
    batch = _batch(4242, N_FALSE_POSITIVE)
    n = len(batch)
    estimated = sum(cal.k1_sigma > 0 for _, cal in batch)
    lo, hi = binom.ppf(BAND_QUANTILE, n, DISTORTION_TEST_LEVEL), binom.ppf(1 - BAND_QUANTILE, n, DISTORTION_TEST_LEVEL)
    assert n >= 0.95 * N_FALSE_POSITIVE
    assert lo <= estimated <= hi, (estimated, n, lo, hi)


def test_the_record_and_console_say_k1_was_held(tmp_path) -> None:
    """``vebuild calibrate`` on undistorted photos whose edges are polylines: each camera record's
    distortion says k1 = 0 ± 0, held, with the test's figures (the report prints that record), and
    the console's mode line says so; ``solve --recalibrate`` then holds k1 (its 1σ 0)."""
    rng = np.random.default_rng(3)
    photos, markers = random_scene(rng)
    for ph in photos:
        ph.segments = {}
        add_segments(ph, rng, 0.7, middle_points=2, polyline_min_length_rel=0.0)
    path = write_project(tmp_path, photos, markers)
    run = subprocess.run([sys.executable, "-m", "vebuild", "calibrate", str(path)], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    cams = json.loads(path.read_text())["calibration"]["cameras"]
    held = [pid for pid, c in cams.items() if c["distortion"]["source"].startswith("k1 held at 0")]
    assert len(held) >= len(photos) - 1
    for pid in held:
        d = cams[pid]["distortion"]
        assert d["k1"] == {"value": 0.0, "sigma": 0.0}
        assert d["corner_displacement_px"]["value"] == 0.0
        assert "LR test: Δχ² = " in d["source"]
        assert "lens distortion k1 held at 0: the lines do not bend" in cams[pid]["mode_reason"]
        assert "k1" not in (cams[pid].get("vanishing_point_prior") or {})
    assert "lens distortion k1 held at 0: the lines do not bend" in run.stdout
