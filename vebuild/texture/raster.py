"""Rasterisation of the CPU reference of texture extraction (:mod:`vebuild.texture.reference`):
the ID buffer of a camera (pass 1) in float64, sampled at pixel centres, a centre exactly on an
edge counted inside, depth compared exactly (the first triangle drawn wins a tie, as with GL's
``<``), the near plane clipped, and the erosion morphological (:func:`rasterise_ids`)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import depth_range, world_to_camera
from vebuild.texture.layout import SceneMesh
from vebuild.texture.lens import pinhole_cover

if TYPE_CHECKING:
    from vebuild.camera import ImageCamera

Array = NDArray[np.float64]

#: Pixels, texels or samples processed at once: bounds the temporary arrays (a few hundred bytes
#: each, so ~100 MB at most).
CHUNK = 1 << 18
#: A pixel centre this far (in barycentric units) outside a triangle still counts as inside, so
#: that a centre on an edge shared by two triangles is never missed by both through rounding.
EDGE_EPS = 1e-12


def scan_triangle(uv: Array, width: int, height: int) -> Iterator[tuple[NDArray[np.intp], NDArray[np.intp], Array]]:
    """The pixel centres (i + ½, j + ½) of a width × height grid covered by one triangle with
    screen corners uv (3, 2), in chunks: (i, j, barycentric coordinates (n, 3)).

    A scanline rasteriser: for each row, the span of x where all three barycentric coordinates are
    ≥ 0 is solved for, widened by a pixel, and every centre in it tested exactly.
    """
    u, v = uv[:, 0], uv[:, 1]
    den = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0])
    if not np.isfinite(den) or abs(den) < 1e-12:
        return
    # λ_k(x, y) = A_k x + B_k y + C_k, the barycentric coordinate of corner k.
    A = np.array([v[1] - v[2], v[2] - v[0], v[0] - v[1]]) / den
    B = np.array([u[2] - u[1], u[0] - u[2], u[1] - u[0]]) / den
    C = np.array([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]) / den
    j_lo = max(0, int(np.ceil(v.min() - 0.5)))
    j_hi = min(height - 1, int(np.floor(v.max() - 0.5)))
    if j_hi < j_lo or u.max() < 0.5 - 1 or u.min() > width + 1:
        return
    j = np.arange(j_lo, j_hi + 1)
    y = j + 0.5
    x_lo = np.full(len(j), -np.inf)
    x_hi = np.full(len(j), np.inf)
    empty = np.zeros(len(j), bool)
    for k in range(3):
        rest = B[k] * y + C[k]
        if A[k] > 0:
            x_lo = np.maximum(x_lo, -rest / A[k])
        elif A[k] < 0:
            x_hi = np.minimum(x_hi, -rest / A[k])
        else:
            empty |= rest < -EDGE_EPS
    with np.errstate(invalid="ignore"):
        i_lo = np.maximum(0, np.ceil(np.clip(x_lo, -2.0, width + 2.0) - 0.5) - 1).astype(np.intp)
        i_hi = np.minimum(width - 1, np.floor(np.clip(x_hi, -2.0, width + 2.0) - 0.5) + 1).astype(np.intp)
    n = np.where(empty, 0, np.maximum(0, i_hi - i_lo + 1))
    keep = n > 0
    j, i_lo, n = j[keep], i_lo[keep], n[keep]
    if not len(j):
        return
    ends = np.cumsum(n)
    start = 0
    while start < len(j):
        # rows [start, stop) with at most CHUNK candidates (at least one row)
        base = ends[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(ends, base + CHUNK, side="right")))
        counts = n[start:stop]
        rows = np.repeat(j[start:stop], counts)
        offs = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
        cols = np.repeat(i_lo[start:stop], counts) + offs
        x = cols + 0.5
        yc = j[start:stop] + 0.5
        inside = np.ones(len(cols), bool)
        lam = []
        for k in range(3):
            lk = A[k] * x + np.repeat(B[k] * yc + C[k], counts)
            inside &= lk >= -EDGE_EPS
            lam.append(lk)
        if inside.all():
            yield cols, rows, np.column_stack(lam)
        elif inside.any():
            yield cols[inside], rows[inside], np.column_stack([lk[inside] for lk in lam])
        start = stop


def _near_plane(mesh: SceneMesh, cam: ImageCamera) -> float:
    """The near plane the GPU's ID pass uses (``Extractor._near_far``)."""
    return depth_range(cam.R, cam.C, mesh.vertices)[0]


def _clip_near(X: Array, near: float) -> tuple[Array, NDArray[np.intp]]:
    """Triangles in camera coordinates (m, 3, 3) clipped to z ≥ near: the pieces (k, 3, 3) and
    the index of the triangle each came from, in draw order."""
    inside = X[:, :, 2] >= near
    n_in = inside.sum(axis=1)
    pieces, origin = [X[n_in == 3]], [np.flatnonzero(n_in == 3)]

    def cut(P: Array, Q: Array) -> Array:  # where segment P → Q meets z = near
        t = (near - P[:, 2]) / (Q[:, 2] - P[:, 2])
        return P + t[:, None] * (Q - P)

    one = np.flatnonzero(n_in == 1)
    if len(one):
        k = np.argmax(inside[one], axis=1)  # the corner in front
        Xi = X[one, k]
        Xj = X[one, (k + 1) % 3]
        Xk = X[one, (k + 2) % 3]
        pieces.append(np.stack([Xi, cut(Xi, Xj), cut(Xi, Xk)], axis=1))
        origin.append(one)
    two = np.flatnonzero(n_in == 2)
    if len(two):
        k = np.argmin(inside[two], axis=1)  # the corner behind
        Xi = X[two, k]
        Xj = X[two, (k + 1) % 3]
        Xk = X[two, (k + 2) % 3]
        a, b = cut(Xj, Xi), cut(Xk, Xi)  # on edges i–j and k–i
        pieces += [np.stack([a, Xj, Xk], axis=1), np.stack([a, Xk, b], axis=1)]
        origin += [two, two]
    P = np.concatenate(pieces)
    o = np.concatenate(origin)
    order = np.argsort(o, kind="stable")
    return P[order], o[order]


def rasterise_ids(mesh: SceneMesh, cam: ImageCamera, erode_px: float = 0.0) -> tuple[NDArray[np.int32], Array]:
    """Pass 1, the ID buffer of ``cam``: (H, W) int32 1-based face id of the nearest triangle at
    each pixel centre (0: nothing) and (H, W) float64 camera depth z there (+inf: nothing).

    Triangles are clipped to the GPU's near plane (z ≥ near, so a triangle partly behind the camera
    keeps its visible part), projected, and scan-converted at pixel centres; depth is interpolated
    perspective-correctly (1/z is affine in the image), the nearest wins and among equal depths the
    one drawn first (mesh order).

    Erosion (``erode_px`` = r > 0) is morphological: a pixel is set to id 0 when some pixel whose
    centre lies at most r pixels from its own centre has a different id (image borders are no
    discontinuity). This approximates the GPU, which draws every visible face border and
    silhouette as a band r pixels either side of the edge, depth-tested with the faces: the band
    reaches r from the edge itself, the morphological mask r from the first centre across it (so
    about ½ px less on average), and the GPU's band is not drawn where a sloping face lies more
    than 0.2 % nearer than the edge (``EDGE_SHRINK``: measured on the example room, the near side
    of a silhouette of a face seen obliquely keeps its pixels), nor across id changes that are no
    edge (two faces passing through each other), where the morphological mask erodes regardless;
    the GPU also erodes next to edges just outside the image, which this mask cannot see.

    For a photo with lens distortion (``cam.lens`` not the pinhole) the ID buffer is that of its
    :func:`~vebuild.texture.lens.pinhole_cover` (the pinhole image over the photo's undistorted
    bounds), as on the GPU.
    """
    cam, _ = pinhole_cover(cam)
    w, h = int(cam.width), int(cam.height)
    ids = np.zeros(h * w, np.int32)
    depth = np.full(h * w, np.inf)
    if len(mesh.triangles):
        near = _near_plane(mesh, cam)
        Xc = world_to_camera(cam.R, cam.C, mesh.vertices)[mesh.triangles]  # (m, 3, 3)
        pieces, origin = _clip_near(Xc, near)
        faces = mesh.triangle_faces[origin]
        H = pieces @ np.asarray(cam.K, float).T
        uv = H[:, :, :2] / H[:, :, 2:3]
        inv_z = 1.0 / pieces[:, :, 2]
        for t in range(len(pieces)):
            for i, j, lam in scan_triangle(uv[t], w, h):
                z = 1.0 / (lam[:, 0] * inv_z[t, 0] + lam[:, 1] * inv_z[t, 1] + lam[:, 2] * inv_z[t, 2])
                idx = j * w + i
                nearer = z < depth[idx]
                depth[idx[nearer]] = z[nearer]
                ids[idx[nearer]] = faces[t]
    id_image, depth_image = ids.reshape(h, w), depth.reshape(h, w)
    if erode_px > 0:
        id_image = np.where(_near_id_change(id_image, erode_px), 0, id_image).astype(np.int32)
    return id_image, depth_image


def _near_id_change(ids: NDArray[np.int32], r: float) -> NDArray[np.bool_]:
    """Pixels with a pixel of another id at most r pixels (centre to centre) away; pixels outside
    the image do not count. One comparison per pair of opposite offsets in the disk."""
    h, w = ids.shape
    out = np.zeros((h, w), bool)
    n = int(np.floor(r))
    for dy in range(0, n + 1):
        for dx in range(-n, n + 1):
            if (dy == 0 and dx <= 0) or dx * dx + dy * dy > r * r:
                continue  # (dy, dx) and (−dy, −dx) are one comparison
            a = (slice(0, h - dy), slice(max(0, -dx), w - max(0, dx)))  # pixel (j, i)
            b = (slice(dy, h), slice(max(0, dx), w - max(0, -dx)))  # pixel (j + dy, i + dx)
            if a[0].start >= a[0].stop or a[1].start >= a[1].stop:
                continue
            differ = ids[a] != ids[b]
            out[a] |= differ
            out[b] |= differ
    return out
