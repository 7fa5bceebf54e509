"""How far a user's clicked points lie from a model edge's image (paper §3.1, the red edge),
through each photo's lens distortion (the division model of vebuild/camera.py): the residual of
an edge observation in the model solver (:mod:`.residuals`).

Layer 1 (DESIGN.md): plain NumPy; no GL, no file I/O.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def edge_distances(Xa: Array, Xb: Array, K: Array, R: Array, C: Array, lens_k: Array, points: Array) -> Array:
    """Each clicked point's signed distance (in the photo's pixels) from the model edge's image: the
    straight line through the edge's ends ``Xa``, ``Xb`` (n, 3) in the pinhole image of camera
    ``K``, ``R``, ``C`` (n, 3, 3), (n, 3, 3), (n, 3) with lens ``lens_k`` (n, 2): each camera's (k1,
    k2), the clicked ``points`` (n, 2, 2) undistorted onto it, the distance scaled back by the
    undistortion's local stretch across the line (first order: exact where the point lies on the
    edge's curve). Returns (n, 2)."""
    ha = np.einsum("nij,nj->ni", K, np.einsum("nij,nj->ni", R, Xa - C))
    hb = np.einsum("nij,nj->ni", K, np.einsum("nij,nj->ni", R, Xb - C))
    line = np.cross(ha, hb)
    line /= np.hypot(line[:, 0], line[:, 1])[:, None]
    k1, k2 = np.asarray(lens_k, float).reshape(-1, 2).T
    if not np.any(k1 != 0.0) and not np.any(k2 != 0.0):
        pts = np.concatenate([points, np.ones((len(points), 2, 1))], axis=2)
        return np.einsum("nkj,nj->nk", pts, line)
    f, c = K[:, 0, 0][:, None, None], K[:, :2, 2][:, None, :]
    xd = (points - c) / f  # (n, 2 points, 2): as the lens put them
    r2 = np.sum(xd**2, axis=-1)
    den = 1.0 + k1[:, None] * r2 + k2[:, None] * r2**2  # x_u = x_d / den
    pu = xd / den[..., None] * f + c
    normal = line[:, None, :2]
    # ∂x_u/∂x_d = (I − (2 k1 + 4 k2 r²) x_d x_dᵀ / den) / den (symmetric): a step δ across the
    # curve in the photo moves the undistorted point by nᵀ J δ across the line.
    Jn = (normal - (2.0 * k1[:, None] + 4.0 * k2[:, None] * r2)[..., None] * xd
          * np.sum(xd * normal, axis=-1, keepdims=True)
          / den[..., None]) / den[..., None]
    dist = np.sum(pu * normal, axis=-1) + line[:, None, 2]
    return dist / np.linalg.norm(Jn, axis=-1)
