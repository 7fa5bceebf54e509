"""The one camera convention (DESIGN.md), checked against independent constructions."""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.camera import (
    ImageCamera,
    Lens,
    exp_so3,
    intrinsic_matrix,
    log_so3,
    nearest_rotation,
    pixel_rays_world,
    project,
    rotation_from_ypr,
    ypr_from_rotation,
)


def test_level_camera_looking_along_x_sees_up_as_up() -> None:
    # yaw = pitch = roll = 0: optical axis +X, image right is world −Y, image down is world −Z.
    R = rotation_from_ypr(0.0, 0.0, 0.0)
    K = intrinsic_matrix(1000.0, 800.0, 600.0)
    C = np.zeros(3)
    centre, right, up = project(K, R, C, np.array([[5.0, 0, 0], [5.0, -1.0, 0], [5.0, 0, 1.0]]))
    assert centre == pytest.approx([800.0, 600.0])
    assert right[0] > 800.0 and right[1] == pytest.approx(600.0)
    assert up[1] < 600.0 and up[0] == pytest.approx(800.0)


def test_yaw_pitch_roll_meaning() -> None:
    R = rotation_from_ypr(np.radians(90), np.radians(20), 0.0)
    axis = R.T @ np.array([0, 0, 1.0])  # optical axis in the world
    assert axis == pytest.approx([0.0, np.cos(np.radians(20)), np.sin(np.radians(20))], abs=1e-12)
    # Positive roll: the camera's right edge goes down (clockwise seen from behind).
    right = rotation_from_ypr(0.0, 0.0, np.radians(10)).T @ np.array([1.0, 0, 0])
    assert right[2] < 0


def test_ypr_round_trip(rng: np.random.Generator) -> None:
    for _ in range(50):
        ypr = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(-1.4, 1.4), rng.uniform(-np.pi, np.pi)])
        R = rotation_from_ypr(*ypr)
        assert np.linalg.det(R) == pytest.approx(1.0)
        assert ypr_from_rotation(R) == pytest.approx(ypr, abs=1e-9)


def test_pixel_rays_are_inverse_of_projection(rng: np.random.Generator) -> None:
    K = intrinsic_matrix(1234.0, 812.5, 590.25)
    R = rotation_from_ypr(0.3, -0.4, 0.05)
    C = np.array([1.0, 2.0, 1.6])
    X = C + R.T @ np.array([0.3, -0.2, 4.0])
    uv = project(K, R, C, X)
    d = pixel_rays_world(K, R, uv)
    assert d == pytest.approx((X - C) / np.linalg.norm(X - C), abs=1e-12)


def test_so3_helpers(rng: np.random.Generator) -> None:
    # log_so3 returns the principal rotation vector (|w| <= pi), so only such samples round-trip:
    # draw until 20 of them have been checked rather than letting a longer one pass unchecked.
    checked = 0
    while checked < 20:
        w = rng.normal(size=3)
        if np.linalg.norm(w) >= np.pi - 1e-6:
            continue
        assert log_so3(exp_so3(w)) == pytest.approx(w, abs=1e-9)
        M = exp_so3(w) + rng.normal(0, 1e-3, (3, 3))
        Q = nearest_rotation(M)
        assert Q @ Q.T == pytest.approx(np.eye(3), abs=1e-12)
        assert np.linalg.det(Q) == pytest.approx(1.0)
        checked += 1


# --- lens distortion: the division model ------------------------------------------------------

def test_division_model_round_trips_and_bends_the_way_its_sign_says():
    from vebuild.camera import distort_pixels, distortion_displacement_px, undistort_pixels

    K = intrinsic_matrix(1000.0, 655.0, 470.0)
    uv = np.random.default_rng(3).uniform([0, 0], [1280, 960], (200, 2))
    for k1 in (-0.25, -0.05, 0.05):
        back = distort_pixels(K, undistort_pixels(K, uv, Lens(k1)), Lens(k1))
        assert np.abs(back - uv).max() < 1e-9
    # Barrel (k1 < 0): a corner's undistorted place lies farther from the principal point.
    corner = np.array([[0.0, 0.0]])
    r_d = np.linalg.norm(corner - K[:2, 2])
    assert np.linalg.norm(undistort_pixels(K, corner, Lens(-0.1)) - K[:2, 2]) > r_d
    assert np.linalg.norm(undistort_pixels(K, corner, Lens(0.1)) - K[:2, 2]) < r_d
    # At the corner (|x_d|² = (655² + 490²)/1000² = 0.669), k1 = −0.05 moves it by
    # r_d · (1 / (1 − 0.05 · 0.669) − 1) = 818.0 · 0.03462 = 28.3 px.
    x2 = (655.0**2 + 490.0**2) / 1e6
    expected = np.sqrt(x2) * 1000.0 * (1.0 / (1.0 - 0.05 * x2) - 1.0)
    assert distortion_displacement_px(K, 1280, 960, Lens(-0.05)) == pytest.approx(expected, rel=1e-12)
    assert distortion_displacement_px(K, 1280, 960, Lens(0.0)) == 0.0


def test_every_projection_agrees_on_the_distortion():
    from vebuild.camera import project_each, undistort_pixels

    rng = np.random.default_rng(4)
    K = intrinsic_matrix(900.0, 640.0, 480.0)
    R = rotation_from_ypr(0.4, -0.2, 0.03)
    C = np.array([0.5, -1.0, 1.6])
    X = C + (R.T @ np.c_[rng.uniform(-0.6, 0.6, (30, 2)), np.ones(30)].T).T * rng.uniform(1, 6, (30, 1))
    k1 = -0.08
    uv = project(K, R, C, X, Lens(k1))
    assert np.abs(project_each([K] * 30, [R] * 30, [C] * 30, X, [(k1, 0.0)] * 30) - uv).max() < 1e-9
    # Undistorting the lens's pixels gives the pinhole's projection; the rays go back to X.
    assert np.abs(undistort_pixels(K, uv, Lens(k1)) - project(K, R, C, X)).max() < 1e-9
    d = (X - C) / np.linalg.norm(X - C, axis=1)[:, None]
    assert np.abs(pixel_rays_world(K, R, uv, Lens(k1)) - d).max() < 1e-12
    # A scaled camera keeps k1 and puts the point at the scaled pixel.
    cam = ImageCamera("p", K, R, C, 1280, 960, lens=Lens(k1))
    half = cam.scaled(0.5)
    assert half.lens == Lens(k1)
    assert np.abs(project(half.K, R, C, X, half.lens) - uv * 0.5).max() < 1e-9
