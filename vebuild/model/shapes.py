"""Small vectorised builders of the primitives' geometry (:mod:`.primitives`): points, a box's
rings, a round primitive's rims, and the frames of level and upright faces.

Parameter arrays (...,) go in, points (..., n, 3) come out, so one call serves a single primitive
and the solver's batches of trial parameters alike. Layer 1 (DESIGN.md): numpy only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]
#: A face frame: origin (3,), x axis (3,), y axis (3,), outward normal (3,); x × y = normal.
Frame = tuple[Array, Array, Array, Array]

#: The unit vectors x̂, ŷ, ẑ.
EX, EY, EZ = np.eye(3)
#: Quad corners v0…v3 as multiples of (width, depth): counter-clockwise from (−x, −y) seen from +z.
_CORNERS = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
#: Rim handle directions at 0°, 90°, 180°, 270° from +x, exact (no cos(π/2) ≈ 6e-17).
_RIM = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])


def points(x: ArrayLike, y: ArrayLike, z: ArrayLike) -> Array:
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def ring(w: Array, d: Array, z: Array) -> Array:
    """The four corners v0…v3 of a w × d rectangle at height z: (...,) → (..., 4, 3)."""
    return points(w[..., None] * _CORNERS[:, 0], d[..., None] * _CORNERS[:, 1], z[..., None])


def rim(r: Array, z: Array) -> Array:
    """Rim points at 0°, 90°, 180°, 270° from +x, radius r, height z: (...,) → (..., 4, 3)."""
    return points(r[..., None] * _RIM[:, 0], r[..., None] * _RIM[:, 1], z[..., None])


def level_frame(z: float, up: bool = True) -> Frame:
    """A level face centred on the z axis; a downward face keeps +x and so takes −y (right-handed)."""
    if up:
        return np.array([0.0, 0.0, z]), EX.copy(), EY.copy(), EZ.copy()
    return np.array([0.0, 0.0, z]), EX.copy(), -EY, -EZ


def side_frame(centre: ArrayLike, n: Array) -> Frame:
    """A vertical face's frame: y up (+z), x = y × n (to the right seen from outside), n out."""
    return np.asarray(centre, float), np.cross(EZ, n), EZ.copy(), np.array(n, float)
