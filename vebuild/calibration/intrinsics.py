"""Closed-form intrinsics and rotation from vanishing points (paper §2, eqs. 1–2).

These give the starting point of the joint refinement in :mod:`.photo`; they are the textbook
relations (Caprile & Torre 1990; Hartley & Zisserman §8.8):

- two orthogonal directions with finite vanishing points v1, v2 and principal point c:
  f² = −(v1 − c)·(v2 − c);
- three orthogonal directions: c is the orthocentre of the triangle v1 v2 v3;
- the rotation's columns are ±K⁻¹vᵢ/‖K⁻¹vᵢ‖, the sign fixed by the segments' direction.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.camera import nearest_rotation

Array = NDArray[np.float64]


def orthocentre(v1: ArrayLike, v2: ArrayLike, v3: ArrayLike) -> Array:
    """The orthocentre of a triangle: the principal point of three orthogonal vanishing points."""
    v1, v2, v3 = (np.asarray(v, float) for v in (v1, v2, v3))
    A = np.array([v2 - v3, v1 - v3])
    b = np.array([v1 @ (v2 - v3), v2 @ (v1 - v3)])
    return np.linalg.solve(A, b)


def focal_squared(v1: ArrayLike, v2: ArrayLike, c: ArrayLike) -> float:
    """f² = −(v1 − c)·(v2 − c) for finite vanishing points of two orthogonal directions."""
    c = np.asarray(c, float)
    return float(-(np.asarray(v1, float) - c) @ (np.asarray(v2, float) - c))


def direction_sign(d_cam: ArrayLike, K: ArrayLike, segments: ArrayLike) -> float:
    """+1 if moving along +d_cam moves the image the way the directed segments run, else −1.

    A 3D point moving along d from the ray through pixel p moves its image, in normalised
    coordinates x = K⁻¹p, with velocity d_xy − x_xy d_z (finite or at infinity alike).
    """
    seg = np.asarray(segments, float)
    Kinv = np.linalg.inv(np.asarray(K, float))
    d = np.asarray(d_cam, float)
    x = np.c_[seg[:, 0:2], np.ones(len(seg))] @ Kinv.T
    vel = d[None, :2] - x[:, :2] * d[2]
    step = (seg[:, 2:4] - seg[:, 0:2]) @ Kinv[:2, :2].T
    s = np.sum(np.einsum("ij,ij->i", vel, step))
    return 1.0 if s >= 0 else -1.0


def rotation_from_vanishing_points(
    K: ArrayLike, points: dict[str, Array], segments: dict[str, Array]
) -> tuple[Array, float]:
    """World→camera rotation from two or three vanishing points (paper eq. 2).

    Parameters
    ----------
    K : (3, 3) intrinsics.
    points : axis ('x', 'y', 'z') → homogeneous vanishing point in pixels.
    segments : axis → (n, 4) directed segments, used only for the signs.

    Returns
    -------
    R : (3, 3) rotation, det +1.
    handedness : det of the sign-fixed matrix before orthonormalisation, in [−1, 1]; negative
        when the marked directions describe a left-handed frame (a segment set drawn backwards).
    """
    Kinv = np.linalg.inv(np.asarray(K, float))
    idx = {"x": 0, "y": 1, "z": 2}
    cols: dict[int, Array] = {}
    for axis, v in points.items():
        d = Kinv @ v
        d /= np.linalg.norm(d)
        cols[idx[axis]] = d * direction_sign(d, K, segments[axis])
    handedness = 1.0
    if len(cols) == 3:
        handedness = float(np.linalg.det(np.column_stack([cols[0], cols[1], cols[2]])))
    else:
        (i, a), (j, b) = sorted(cols.items())
        k = 3 - i - j
        # The missing column completes a right-handed frame: e_k = e_i × e_j in cyclic order.
        cols[k] = np.cross(a, b) if (i, j) in ((0, 1), (1, 2)) else np.cross(b, a)
    M = np.column_stack([cols[0], cols[1], cols[2]])
    return nearest_rotation(M), handedness
