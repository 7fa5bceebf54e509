"""Which part of a sight line's or a viewshed's answer rests on surfaces no photo saw (numpy).

A ray's answer rests on the surface that decides it: a hidden ray on the first surface in its way
(the blocker), a ray that reaches a sample of a target object on that sample's own surface. The
surface there is *unobserved* when no photo saw the texel the point falls on (the scene's masks,
from the coverage maps: :mod:`vebuild.render.observed`); that part of the model was inferred
(placed from the photos that saw its other faces, its extent assumed), so an answer resting on
it is only as good as that inference. A target point that is seen rests on no surface (nothing is
in the way); it is reported as resting on none.

Where the scene has no masks (no textures, or a coverage map missing) nothing can be said: the
figures are None, never 0.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.analysis.rays import Occluders

Array = NDArray[np.float64]


def known(occ: Occluders) -> bool:
    """Whether the scene records per texel which surfaces a photo saw."""
    scene = occ.scene
    return bool(scene.textured and scene.masks and len(scene.masks) == len(scene.mesh.pages))


def unobserved_at(occ: Occluders, tri: NDArray[np.intp], points: Array) -> NDArray[np.bool_] | None:
    """For each world point on triangle ``tri`` (index into the scene's triangles), whether no
    photo saw the texel it falls on (None where the scene has no masks)."""
    if not known(occ):
        return None
    tri = np.asarray(tri, np.intp)
    out = np.zeros(len(tri), bool)
    if not len(tri):
        return out
    mesh = occ.scene.mesh
    P = np.asarray(points, float) - occ.v0[tri]
    e1, e2 = occ.e1[tri], occ.e2[tri]
    # Barycentric coordinates of each point in its triangle (least squares in the triangle's plane).
    d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    p1, p2 = (P * e1).sum(1), (P * e2).sum(1)
    det = np.maximum(d11 * d22 - d12 * d12, 1e-300)
    b1, b2 = (d22 * p1 - d12 * p2) / det, (d11 * p2 - d12 * p1) / det
    b1, b2 = np.clip(b1, 0.0, 1.0), np.clip(b2, 0.0, 1.0)
    corners = mesh.triangles[tri]
    A = mesh.atlas[corners]  # (n, 3, 2) texels
    uv = A[:, 0] + b1[:, None] * (A[:, 1] - A[:, 0]) + b2[:, None] * (A[:, 2] - A[:, 0])
    pages = np.array([mesh.faces[int(f) - 1].page for f in occ.face_id[tri]], np.intp)
    for k in np.unique(pages):
        sel = pages == k
        mask = occ.scene.masks[int(k)]
        col = np.clip(np.floor(uv[sel, 0]).astype(np.intp), 0, mask.shape[1] - 1)
        row = np.clip(np.floor(uv[sel, 1]).astype(np.intp), 0, mask.shape[0] - 1)
        out[sel] = mask[row, col] > 127
    return out


def hit_points(E: Array, ends: Array, t: Array) -> Array:
    """Where segments from ``E`` (one eye, or one per segment) towards ``ends`` first meet a surface,
    ``t`` metres from ``E``."""
    d = ends - E
    return E + d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-300) * np.asarray(t)[:, None]


def blocker_unobserved(occ: Occluders, E: Array, end: Array, t: float, tri: int) -> bool | None:
    """Whether the surface blocking the segment from ``E`` to ``end`` (``t`` m from ``E``, on
    triangle ``tri``) is one no photo saw."""
    u = unobserved_at(occ, np.array([tri]), hit_points(np.asarray(E, float), np.asarray(end, float)[None],
                                                      np.array([t])))
    return None if u is None else bool(u[0])


def object_rays(occ: Occluders, E: Array, P: Array, facing: NDArray[np.bool_], vis: NDArray[np.bool_],
                t: Array, tri: NDArray[np.intp], tri_of_sample: NDArray[np.intp]) -> dict[str, Any] | None:
    """The unobserved share of one eye's answer for an object's samples ``P``: of all samples, the
    share seen on surfaces no photo saw and the share hidden by surfaces no photo saw, and of the
    samples whose answer a surface decides (seen, or facing the eye and hidden), the share that
    rests on unobserved ones. ``t``, ``tri``: each hidden sample's first blocker;
    ``tri_of_sample``: the triangle each sample lies on. None where the scene has no masks."""
    if not known(occ):
        return None
    n = len(P)
    seen_on = unobserved_at(occ, tri_of_sample[vis], P[vis])
    hidden = np.flatnonzero(facing & ~vis)
    hid_by = unobserved_at(occ, tri[hidden], hit_points(np.asarray(E, float), P[hidden], t[hidden]))
    assert seen_on is not None and hid_by is not None
    decided = int(vis.sum()) + len(hidden)
    return {"visible_on_unobserved_share": round(float(seen_on.sum()) / n, 6) if n else 0.0,
            "hidden_by_unobserved_share": round(float(hid_by.sum()) / n, 6) if n else 0.0,
            "rests_on_unobserved_share": round(float(seen_on.sum() + hid_by.sum()) / decided, 6) if decided else 0.0}


def viewshed_figures(weight: Array | None, seeing: NDArray[np.bool_], places: NDArray[np.bool_],
                     cell: float) -> dict[str, Any]:
    """A viewshed's figures for unobserved surfaces: the area (m²) and share of the places that
    see the target, and of those that do not, whose answer rests on surfaces no photo saw (each
    place weighted by the share of its deciding rays that do; ``weight`` None: unknown)."""
    keys = ("seeing_area_resting_on_unobserved_m2", "seeing_share_resting_on_unobserved",
            "hidden_area_resting_on_unobserved_m2", "hidden_share_resting_on_unobserved")
    if weight is None:
        return dict.fromkeys(keys)
    a = cell ** 2
    w = np.nan_to_num(weight)
    hidden = places & ~seeing
    s_area, h_area = float(w[seeing].sum() * a), float(w[hidden].sum() * a)
    return {keys[0]: round(s_area, 6), keys[1]: round(s_area / (seeing.sum() * a), 6) if seeing.any() else None,
            keys[2]: round(h_area, 6), keys[3]: round(h_area / (hidden.sum() * a), 6) if hidden.any() else None}


def hidden_weights(occ: Occluders, E: Array, ends: Array, blocked: NDArray[np.bool_], t: Array,
                   tri: NDArray[np.intp]) -> Array | None:
    """Per segment from ``E`` to ``ends``: 1 where it is blocked by a surface no photo saw, else 0
    (None where the scene has no masks)."""
    E, ends = np.broadcast_arrays(np.asarray(E, float), np.asarray(ends, float))
    b = np.flatnonzero(blocked)
    u = unobserved_at(occ, tri[b], hit_points(E[b], ends[b], t[b]))
    if u is None:
        return None
    w = np.zeros(len(blocked))
    w[b] = u
    return w


def on_grid(w: Array | None, places: NDArray[np.intp], ny: int, nx: int) -> Array | None:
    """Per-place values ``w`` laid on a (ny, nx) grid (NaN elsewhere); None stays None."""
    if w is None:
        return None
    out = np.full(nx * ny, np.nan)
    out[places] = w
    return out.reshape(ny, nx)
