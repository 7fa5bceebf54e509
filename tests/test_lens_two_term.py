"""The two-term division lens of vebuild/camera.py: its round trips, its rim, its derivatives,
one projection through every path that does not draw, and its record read back or refused.

The lens is the two-term fit of an equidistant 150° (diagonal) fisheye on a 1280×720 frame
(scripts/lens_models.py: f = 560.4 px, k1 = −0.3276, k2 = −0.0291, worst error 0.55 px against
the true fisheye), the widest lens vebuild models.
"""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.analysis.single_view import floor_distance_on_photo, height_on_photo
from vebuild.camera import (
    PINHOLE,
    ImageCamera,
    Lens,
    distort_normalised,
    distort_pixels,
    distortion_derivatives,
    distortion_displacement_px,
    distortion_scale,
    intrinsic_matrix,
    look_rotation,
    pixel_rays_world,
    project,
    project_each,
    undistort_normalised,
    undistort_pixels,
)
from vebuild.project.records import distortion_record

W, H = 1280, 720
FISHEYE = Lens(-0.3276, -0.0291)
K = intrinsic_matrix(560.4, 643.0, 357.5)
#: The inversion's stated accuracy is 1e-13 relative on the normalised radius (camera.NEWTON_RTOL);
#: at r_d ≈ 1.3 and f = 560 px that is ~1e-10 px: 1e-9 px leaves a factor 10 for rounding.
ROUND_TRIP_PX = 1e-9


def _frame_pixels(n: int = 4001) -> np.ndarray:
    rng = np.random.default_rng(11)
    corners = np.array([[0.0, 0.0], [W, 0.0], [0.0, H], [W, H]])
    return np.r_[rng.uniform([0, 0], [W, H], (n, 2)), corners, K[:2, 2][None]]


def test_a_fisheye_frame_round_trips_to_a_billionth_of_a_pixel() -> None:
    uv = _frame_pixels()
    pin = undistort_pixels(K, uv, FISHEYE)
    # the corners of a 150° lens lie far outside the pinhole's frame: a real test of the inversion
    assert np.max(np.linalg.norm(pin - K[:2, 2], axis=1)) > 2.5 * np.hypot(W, H) / 2
    assert np.max(np.linalg.norm(distort_pixels(K, pin, FISHEYE) - uv, axis=1)) < ROUND_TRIP_PX
    # and the other way: pinhole points inside the lens's field
    x_u = np.random.default_rng(12).uniform(-3.5, 3.5, (4000, 2))
    x_d = distort_normalised(x_u, FISHEYE)
    assert np.max(np.abs(undistort_normalised(x_d, FISHEYE) - x_u) * K[0, 0]) < ROUND_TRIP_PX * 10.0


def test_k2_zero_is_the_one_term_closed_form_exactly() -> None:
    r2 = np.linspace(0.0, 2.0, 501)
    for k1 in (-0.3, -0.05, 0.05):
        closed = 2.0 / (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * k1 * r2, 0.0)))
        np.testing.assert_array_equal(distortion_scale(r2, Lens(k1)), closed)
        np.testing.assert_array_equal(distortion_scale(r2, Lens(k1, 0.0)), closed)


def test_the_rim_is_where_the_lens_stops_opening_out() -> None:
    """A pincushion lens (g(r) = r / (1 + k1 r² + k2 r⁴) has a maximum): its rim is where g' = 0,
    1 − k1 t − 3 k2 t² = 0 (t = r²); a pinhole point beyond g(rim) is put on the rim, one inside
    is inverted exactly, and the map is monotone up to it."""
    lens = Lens(0.1, 0.3)
    t = (-0.1 + np.sqrt(0.01 + 12 * 0.3)) / (6 * 0.3)
    assert lens.rim() == pytest.approx(np.sqrt(t), rel=1e-12) and lens.rim_is_field_edge()
    g_rim = lens.rim() / (1 + lens.k1 * t + lens.k2 * t * t)
    r_u = np.linspace(0.0, 3.0 * g_rim, 3001)
    r_d = distortion_scale(r_u**2, lens) * r_u
    assert np.all(np.diff(r_d) >= -1e-15)  # monotone, to the rounding of r_d = s · r_u
    beyond = r_u >= g_rim
    np.testing.assert_allclose(r_d[beyond], lens.rim(), rtol=1e-12)
    inside = ~beyond
    np.testing.assert_allclose(r_d[inside] / (1 + lens.k1 * r_d[inside] ** 2 + lens.k2 * r_d[inside] ** 4),
                               r_u[inside], rtol=1e-12, atol=1e-15)
    # a barrel fisheye has no edge: its model's denominator vanishes first, and every pinhole point
    # (however far) lies inside that pole
    assert not FISHEYE.rim_is_field_edge()
    far = distortion_scale(np.array([1e6]), FISHEYE) * 1e3
    assert far[0] < FISHEYE.rim()


def test_the_derivatives_agree_with_central_differences() -> None:
    r2 = np.linspace(0.05, 8.0, 40)
    s, ds_dr2, ds_dk1, ds_dk2 = distortion_derivatives(r2, FISHEYE)
    h = 1e-6
    num_r2 = (distortion_scale(r2 + h, FISHEYE) - distortion_scale(r2 - h, FISHEYE)) / (2 * h)
    num_k1 = (distortion_scale(r2, Lens(FISHEYE.k1 + h, FISHEYE.k2))
              - distortion_scale(r2, Lens(FISHEYE.k1 - h, FISHEYE.k2))) / (2 * h)
    num_k2 = (distortion_scale(r2, Lens(FISHEYE.k1, FISHEYE.k2 + h))
              - distortion_scale(r2, Lens(FISHEYE.k1, FISHEYE.k2 - h))) / (2 * h)
    # central differences of a smooth function at h = 1e-6: truncation ~h² s''' and rounding
    # ~1e-16 / h, both below 1e-7 here
    np.testing.assert_allclose(ds_dr2, num_r2, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(ds_dk1, num_k1, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(ds_dk2, num_k2, rtol=1e-6, atol=1e-8)
    np.testing.assert_array_equal(s, distortion_scale(r2, FISHEYE))


def _camera() -> ImageCamera:
    C = np.array([0.4, 0.3, 2.5])
    R = look_rotation(np.array([3.5, 3.0, 0.4]) - C)
    cov = np.diag([4.0, 4.0, 4.0, 1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4])
    return ImageCamera("cctv", K, R, C, W, H, lens=FISHEYE, covariance=cov)


def test_every_projection_of_a_fisheye_camera_agrees() -> None:
    cam = _camera()
    rng = np.random.default_rng(13)
    uv = rng.uniform([0, 0], [W, H], (200, 2))
    depth = rng.uniform(0.5, 8.0, 200)
    X = cam.C + pixel_rays_world(cam.K, cam.R, uv, cam.lens) * depth[:, None]
    # the rays of the photo's pixels project back onto them, one camera or many at once
    assert np.max(np.linalg.norm(project(cam.K, cam.R, cam.C, X, cam.lens) - uv, axis=1)) < 1e-8
    n = len(X)
    each = project_each([cam.K] * n, [cam.R] * n, [cam.C] * n, X, [(FISHEYE.k1, FISHEYE.k2)] * n)
    assert np.max(np.linalg.norm(each - uv, axis=1)) < 1e-8
    # a scaled camera keeps the lens (x is divided by f)
    half = cam.scaled(0.5)
    assert half.lens == FISHEYE
    assert np.max(np.abs(project(half.K, half.R, half.C, X, half.lens) - 0.5 * uv)) < 1e-8
    # the same lens as one term only puts these points tens of pixels elsewhere (32 px at most here)
    assert np.max(np.linalg.norm(project(cam.K, cam.R, cam.C, X, Lens(FISHEYE.k1)) - uv, axis=1)) > 20.0


def test_single_view_measurements_see_through_the_fisheye() -> None:
    """A height and a floor distance clicked where the fisheye puts them come out as built, and
    k2's 1σ (with its correlation to k1) widens their 1σ."""
    cam = _camera()
    # a foot near the frame's lower left, where k2 matters (found from its pixel's ray)
    d = pixel_rays_world(cam.K, cam.R, np.array([150.0, 650.0]), cam.lens)
    foot = cam.C + d * (-cam.C[2] / d[2])
    top, other = foot + [0.0, 0.0, 1.0], np.array([3.5, 2.0, 0.0])
    uv = project(cam.K, cam.R, cam.C, np.array([foot, top, other]), cam.lens)
    h = height_on_photo(cam, uv[0], uv[1], click_sigma_px=0.0)
    assert h.value == pytest.approx(1.0, abs=1e-6)
    d = floor_distance_on_photo(cam, uv[0], uv[2], click_sigma_px=0.0)
    assert d.value == pytest.approx(float(np.linalg.norm(other - foot)), abs=1e-6)
    # through the one-term part alone the same clicks measure 0.979 m: 2 % short
    pinholeish = ImageCamera("cctv", K, cam.R, cam.C, W, H, lens=Lens(FISHEYE.k1), covariance=cam.covariance)
    assert abs(height_on_photo(pinholeish, uv[0], uv[1], click_sigma_px=0.0).value - 1.0) > 0.01
    s0 = height_on_photo(cam, uv[0], uv[1], click_sigma_px=0.5, k1_sigma=0.003).sigma
    s_indep = height_on_photo(cam, uv[0], uv[1], click_sigma_px=0.5, k1_sigma=0.003, k2_sigma=0.002).sigma
    s_corr = height_on_photo(cam, uv[0], uv[1], click_sigma_px=0.5, k1_sigma=0.003, k2_sigma=0.002,
                             k1_k2_correlation=-0.9).sigma
    # k2's own 1σ widens the height's; k1 and k2 bend the same way, so their usual strong negative
    # correlation (a joint fit trades one for the other) takes much of that back
    assert s_indep > s0 > 0.0 and s_corr < s_indep


def test_the_record_carries_k2_beside_k1() -> None:
    rec = distortion_record(K, W, H, FISHEYE.k1, 0.003, "segments", k2=FISHEYE.k2, k2_sigma=0.002,
                            k2_source="segments", corner_sigma=25.0, k1_correlation=-0.95)
    assert rec["k2"] == {"value": FISHEYE.k2, "sigma": 0.002, "source": "segments", "k1_correlation": -0.95}
    assert rec["corner_displacement_px"]["value"] == pytest.approx(distortion_displacement_px(K, W, H, FISHEYE))
    assert rec["corner_displacement_px"]["sigma"] == 25.0
    # a one-term lens's record is as it was: no k2
    assert "k2" not in distortion_record(K, W, H, -0.05, 0.002, "user")
    assert distortion_displacement_px(K, W, H, PINHOLE) == 0.0


def test_the_report_shows_k2_only_where_the_lens_has_one() -> None:
    from vebuild.report.cameras import lens

    one = {"distortion": distortion_record(K, W, H, -0.05, 0.002, "user")}
    assert "k2" not in lens(one) and lens(one).startswith("k1 -0.0500 ± 0.0020, corners ")
    held = {"distortion": distortion_record(K, W, H, -0.3, 0.004, "segments", k2_source="k2 held at 0: …")}
    assert "k2" not in lens(held)
    two = {"distortion": distortion_record(K, W, H, FISHEYE.k1, 0.003, "segments", k2=FISHEYE.k2, k2_sigma=0.002,
                                           k2_source="segments")}
    assert "k1 -0.3276 ± 0.0030, k2 -0.0291 ± 0.0020, corners " in lens(two)
