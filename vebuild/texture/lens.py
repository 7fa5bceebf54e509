"""A lens seen through a pinhole: the pinhole image that covers everything a distorted photo shows.

A photo taken through a lens with distortion ``k1``, ``k2`` (the division model of :mod:`vebuild.camera`)
shows, at its corners, what the pinhole camera of the same K puts outside its own frame (barrel
distortion, k1 < 0) or inside it (pincushion, k1 > 0). GL rasterises pinholes only, so every pass
that needs to know what a distorted photo sees draws a pinhole image over the photo's *undistorted
bounds* and meets the lens once, through the closed-form formulas, where it maps a pixel:

* texture extraction: the ID buffer covers the undistorted bounds; a texel is tested there at its
  pinhole pixel and then sampled in the photo at that pixel distorted (``shaders/texel.frag``);
* a photo camera's render: the scene is drawn as this pinhole and resampled through the lens to
  the photo's size (``shaders/lens.frag``).

The covering camera has the photo's f, R and C and K's principal point moved by a whole number of
pixels, so that its pixel grid is the pinhole's grid of K shifted: pinhole pixel p of the photo's
K is pixel p − origin of the cover. The ID buffer's erosion (``erode_px``) is thus counted in the
pinhole's pixels, which are the photo's at its centre and, with barrel distortion, a little
smaller than the photo's towards its corners (by the lens's local scale there: a few per cent for
a real lens). No GL here.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, pixels_to_normalised, undistort_pixels
from vebuild.errors import VebuildError

#: Whole pixels added around the undistorted bounds: the bounds are found from the photo's border
#: sampled once per pixel (exact at the corners, where barrel distortion has its extremes; within
#: a small fraction of a pixel at the edges' middles, where pincushion has them), and a texel at
#: the photo's very border has its footprint's corners (± ½ px) tested in the ID buffer too.
COVER_MARGIN_PX = 1
#: The least 1 + k1 r² + k2 r⁴ (r = |x_d|) at the photo's border: the pinhole puts a corner 1 / (1 + k1 r² + k2 r⁴)
#: times farther from the principal point than the lens, so 0.25 covers a barrel lens whose pinhole
#: image is four times the photo's size per side (sixteen times its pixels). A real lens is far
#: inside this (a 2–3 % corner displacement is 0.97); a value past it is a wrong calibration, and
#: at 0 the corners are at infinity.
MIN_CORNER_DENOMINATOR = 0.25


def border_pixels(width: int, height: int) -> NDArray[np.float64]:
    """(n, 2) points along the border of a width × height image, one per pixel, corners included
    (pixel positions, the image spanning [0, width] × [0, height])."""
    u = np.linspace(0.0, float(width), int(width) + 1)
    v = np.linspace(0.0, float(height), int(height) + 1)
    return np.concatenate([np.column_stack([u, np.zeros_like(u)]), np.column_stack([u, np.full_like(u, height)]),
                           np.column_stack([np.zeros_like(v), v]), np.column_stack([np.full_like(v, width), v])])


def pinhole_cover(cam: ImageCamera) -> tuple[ImageCamera, tuple[int, int]]:
    """The pinhole camera (k1 = 0) whose image covers everything ``cam``'s photo shows, and its
    origin: the cover's pixel corner (0, 0) in the pinhole pixels of ``cam.K`` (whole pixels, ≤ 0
    where the cover reaches beyond the photo's frame).

    A pinhole camera (k1 = 0) is its own cover, with origin (0, 0): the very object, so that
    every pass given a pinhole does exactly what it did before lenses were modelled.
    """
    if cam.lens.is_pinhole:
        return cam, (0, 0)
    border = border_pixels(cam.width, cam.height)
    r2 = np.sum(pixels_to_normalised(cam.K, border) ** 2, axis=-1)
    k1, k2 = cam.lens.k1, cam.lens.k2
    least = float(np.min(1.0 + k1 * r2 + k2 * r2**2))
    if not least >= MIN_CORNER_DENOMINATOR:
        raise VebuildError(
            f"photo {cam.id}: its lens distortion k1 = {k1:g}{f', k2 = {k2:g}' if k2 else ''} (division model) "
            "puts the corners "
            f"of the {cam.width}×{cam.height} photo {1.0 / max(least, 1e-12):.1f} times farther out than a pinhole "
            f"would; expected at most {1.0 / MIN_CORNER_DENOMINATOR:g} times (1 + k1·r² + k2·r⁴ ≥ "
            f"{MIN_CORNER_DENOMINATOR:g} at the corners): the calibration's distortion is not a real lens; "
            "calibrate the photo again")
    uv = undistort_pixels(cam.K, border, cam.lens)
    lo = np.floor(uv.min(axis=0)).astype(int) - COVER_MARGIN_PX
    hi = np.ceil(uv.max(axis=0)).astype(int) + COVER_MARGIN_PX
    K = np.array(cam.K, float)
    K[0, 2] -= lo[0]
    K[1, 2] -= lo[1]
    cover = ImageCamera(cam.id, K, cam.R, cam.C, int(hi[0] - lo[0]), int(hi[1] - lo[1]),
                        source=f"{cam.source or 'photo ' + repr(cam.id)}, drawn as a pinhole over the lens's field")
    return cover, (int(lo[0]), int(lo[1]))


def cover_growth(cam: ImageCamera) -> float:
    """How many times the photo's pixels its :func:`pinhole_cover` has (1 for a pinhole)."""
    cover, _ = pinhole_cover(cam)
    return cover.width * cover.height / max(1, cam.width * cam.height)


def lens_uniforms(cam: ImageCamera) -> dict[str, object]:
    """The lens's uniforms of the GLSL passes: ``k1``, ``k2``, the cover's ``id_origin`` (its corner in the
    photo's pinhole pixels) and ``id_size``."""
    cover, origin = pinhole_cover(cam)
    return {"k1": float(cam.lens.k1), "k2": float(cam.lens.k2), "id_origin": (float(origin[0]), float(origin[1])),
            "id_size": (float(cover.width), float(cover.height))}

