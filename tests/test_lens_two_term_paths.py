"""A fisheye camera (two-term lens) projects the same through the paths that carry a lens to GL
and to other programs: the pinhole cover of the GL passes, the texture reference's footprint, the
hand-off's undistorted photo plane and the shaders' uniforms (CPU side only: no drawing here).
"""

from __future__ import annotations

import numpy as np

from vebuild.camera import ImageCamera, Lens, distort_pixels, intrinsic_matrix, look_rotation, undistort_pixels
from vebuild.render.export import distortion_extras
from vebuild.render.export_camera import PLANE_ERROR_PX, photo_plane, plane_error_px
from vebuild.texture.lens import border_pixels, lens_uniforms, pinhole_cover
from vebuild.texture.reference import _distort

W, H = 1280, 720
FISHEYE = Lens(-0.3276, -0.0291)  # the two-term fit of an equidistant 150° lens (test_lens_two_term.py)
K = intrinsic_matrix(560.4, 643.0, 357.5)


def _camera() -> ImageCamera:
    C = np.array([0.4, 0.3, 2.5])
    return ImageCamera("cctv", K, look_rotation(np.array([3.5, 3.0, 0.4]) - C), C, W, H, lens=FISHEYE)


def test_the_pinhole_cover_holds_everything_the_fisheye_shows() -> None:
    cam = _camera()
    cover, origin = pinhole_cover(cam)
    und = undistort_pixels(cam.K, border_pixels(W, H), cam.lens) - np.array(origin, float)
    assert np.all(und >= 0.0) and np.all(und[:, 0] <= cover.width) and np.all(und[:, 1] <= cover.height)
    # the cover is the photo's pinhole shifted by whole pixels, and a pinhole itself
    assert cover.lens.is_pinhole and np.array_equal(cover.K[:2, 2], cam.K[:2, 2] - origin)
    # ... and far larger than the photo: a 150° lens's corners lie ~2.9 times farther out
    assert cover.width > 2 * W and cover.height > 2 * H
    u = lens_uniforms(cam)
    assert (u["k1"], u["k2"]) == (FISHEYE.k1, FISHEYE.k2)


def test_the_texture_reference_distorts_as_the_camera_does() -> None:
    rng = np.random.default_rng(17)
    p = undistort_pixels(K, rng.uniform([50, 50], [W - 50, H - 50], (300, 2)), FISHEYE)
    a, b = rng.normal(0.0, 0.3, (300, 2)), rng.normal(0.0, 0.3, (300, 2))
    pd, ad, bd, inside = _distort(K, FISHEYE, p, a, b, W, H)
    np.testing.assert_allclose(pd, distort_pixels(K, p, FISHEYE), atol=1e-9)
    # the footprint is the distortion's Jacobian applied to a, b: central differences agree to
    # the second order of the 0.3 px steps (curvature ~1e-4 / px on these frames: < 1e-4 px)
    h = 1e-3
    num_a = (distort_pixels(K, p + h * a, FISHEYE) - distort_pixels(K, p - h * a, FISHEYE)) / (2 * h)
    np.testing.assert_allclose(ad, num_a, atol=1e-6)
    assert inside.all()


def test_the_handoff_photo_plane_undistorts_the_fisheye() -> None:
    cam = _camera()
    pos, tex, tris, err = photo_plane(cam)
    assert 0.0 < err <= PLANE_ERROR_PX and len(tris) > 2
    assert plane_error_px(cam, pos, tex, tris) == err
    # each vertex sits where the pinhole puts the photo pixel its texture coordinate names
    exact = distort_pixels(K, pos[:, :2] * K[0, 0] + K[:2, 2], cam.lens)
    np.testing.assert_allclose(exact, tex * np.array([W, H]), atol=1e-8)
    extras = distortion_extras(cam)
    assert extras["k2"] == FISHEYE.k2 and "k2 r^4" in extras["definition"]
