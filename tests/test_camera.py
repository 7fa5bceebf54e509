"""The one camera convention (DESIGN.md), checked against independent constructions."""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.camera import (
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
