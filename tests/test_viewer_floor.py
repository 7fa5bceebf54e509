"""The walk-through's floor grid and frustums without a window (vebuild.viewer.floor): lines drawn
through a distorting lens stay on the floor's image, a photo's frustum meets its corners, and the
grid fades with distance."""

from __future__ import annotations

import numpy as np

from vebuild.camera import ImageCamera, Lens, intrinsic_matrix, look_rotation, world_to_camera
from vebuild.camera import project as project_points
from vebuild.viewer import floor as fl

#: A chord of MAX_PIECE_PX through a lens whose bending over that length is a small fraction of a
#: pixel: the drawn line strays from the true curve by less than this (pixels).
CHORD_TOLERANCE_PX = 0.25
#: Even pieces along the 25 m line before the lens's cuts (about 3 m each).
PIECES = 8


def _camera(k1: float) -> ImageCamera:
    """A 1600×1200 camera 1.5 m above the floor looking down 20° along +y, with a barrel lens."""
    R = look_rotation(np.array([0.0, np.cos(np.radians(20)), -np.sin(np.radians(20))]))
    return ImageCamera("p", intrinsic_matrix(1100.0, 790.0, 610.0), R, np.array([0.3, -0.2, 1.5]), 1600, 1200,
                       lens=Lens(k1))


def test_a_grid_line_through_a_barrel_lens_stays_on_the_floor_s_image():
    cam = _camera(-0.25)
    a, b = np.array([-3.0, -5.0, 0.0]), np.array([-3.0, 20.0, 0.0])
    P, uv = fl.polyline_points(cam, a, b, PIECES)
    assert np.allclose(P[:, 0], -3.0) and np.allclose(P[:, 2], 0.0)
    depth = world_to_camera(cam.R, cam.C, P)[:, 2]
    assert depth.min() > fl.NEAR_M - 1e-9 and abs(depth.min() - fl.NEAR_M) < 1e-9  # cut where it passes behind
    assert np.allclose(uv, project_points(cam.K, cam.R, cam.C, P, cam.lens))
    inside = (uv[:, 0] > 0) & (uv[:, 0] < cam.width) & (uv[:, 1] > 0) & (uv[:, 1] < cam.height)
    assert inside.sum() > 10
    # Between two drawn points the true image of the floor line (its world midpoint, through the
    # lens) lies within a fraction of a pixel of the straight piece drawn.
    worst = 0.0
    for k in np.flatnonzero(inside[:-1] & inside[1:]):
        m = project_points(cam.K, cam.R, cam.C, 0.5 * (P[k] + P[k + 1]), cam.lens)
        d = uv[k + 1] - uv[k]
        n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        worst = max(worst, abs(float((m - uv[k]) @ n)))
    assert worst < CHORD_TOLERANCE_PX
    # Cut into the world-even pieces alone, the lens's bending would show (the cuts are needed).
    t = np.linspace(0.0, 1.0, PIECES + 1)
    Q = P[0] + t[:, None] * (P[-1] - P[0])
    q = project_points(cam.K, cam.R, cam.C, Q, cam.lens)
    m = project_points(cam.K, cam.R, cam.C, 0.5 * (Q[:-1] + Q[1:]), cam.lens)
    d = q[1:] - q[:-1]
    n = np.c_[-d[:, 1], d[:, 0]] / np.linalg.norm(d, axis=1)[:, None]
    ok = (q[:-1, 0] > 0) & (q[:-1, 0] < 1600) & (q[:-1, 1] > 0) & (q[:-1, 1] < 1200)
    assert np.abs(((m - q[:-1]) * n).sum(axis=1))[ok].max() > CHORD_TOLERANCE_PX


def test_a_segment_behind_the_camera_is_not_drawn():
    cam = _camera(0.0)
    assert fl.polyline(cam, np.array([0.0, -3.0, 0.0]), np.array([1.0, -4.0, 0.0])) is None


def test_a_photo_s_frustum_meets_its_corners_and_its_foot():
    cam = _camera(-0.25)
    segs = fl.frustum_segments(cam)
    corners = np.array([b for a, b in segs[:4]])
    px = project_points(cam.K, cam.R, cam.C, corners, cam.lens)
    assert np.allclose(px, [[0, 0], [1600, 0], [1600, 1200], [0, 1200]], atol=1e-6)
    assert np.allclose(segs[-1][1], [0.3, -0.2, 0.0])  # the plumb line to the floor


def test_the_grid_fades_with_distance_and_reaches_past_the_cameras():
    cam = _camera(0.0)
    d = np.array([0.0, 2.0, 4.5, 9.0, 15.0, 30.0])
    f = fl.grid_fade(cam, np.c_[cam.C[0] + d, np.full(6, cam.C[1]), np.zeros(6)])
    assert list(f[:3]) == [1.0, 1.0, 1.0] and 0 < f[3] < 1 and f[4] == f[5] == 0.0
    assert fl.grid_half_size([cam]) == int(np.ceil(np.hypot(0.3, 0.2) + fl.GRID_REACH_HEIGHTS * 1.5))
    assert fl.grid_half_size([]) == fl.GRID_MIN_HALF_SIZE
