"""The room primitive's textured mesh: its logical faces as patches (FORMAT.md, "The room primitive").

``floor`` (and ``ceiling``) is the floor polygon, cut into triangles by ear clipping so that an
L-shaped or any other non-convex floor is covered exactly once; ``wall{i}`` and ``outer{i}`` are a
wall's inner and outer faces with its openings as rectangular holes, cut into the cells of the
grid that the openings' jambs, sills and heads make (no triangulation library, no T-junctions);
``wtop{i}`` is the top of wall i when there is no ceiling; ``{name}_reveal`` is an opening's sill,
jambs and head across the wall's thickness, unrolled side by side into one chart.

Layer 1 (DESIGN.md): numpy only; no GL, no file I/O.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .mesh import Patch, polygon_patch
from .room_checks import RoomShape

Array = NDArray[np.float64]

_EZ = np.array([0.0, 0.0, 1.0])


def ear_clip(poly: Array) -> NDArray[np.intp]:
    """(N − 2, 3) triangles, counter-clockwise, covering a simple counter-clockwise polygon (N, 2)
    exactly once (convex or not): repeatedly cut off a convex corner whose triangle holds no other
    corner. O(N²) per ear, ample for rooms."""
    n = len(poly)
    idx = list(range(n))
    tris: list[tuple[int, int, int]] = []

    def cross(o: Array, a: Array, b: Array) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    scale = max(1.0, float(np.abs(poly).max())) ** 2 * 1e-12
    while len(idx) > 3:
        m = len(idx)
        for k in range(m):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % m]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if cross(a, b, c) <= scale:
                continue  # a reflex (or flat) corner is no ear
            inside = False
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                p = poly[j]
                if cross(a, b, p) >= -scale and cross(b, c, p) >= -scale and cross(c, a, p) >= -scale:
                    inside = True
                    break
            if not inside:
                tris.append((i0, i1, i2))
                del idx[k]
                break
        else:  # numerically flat remainder (collinear corners): fan it, nothing is lost
            tris += [(idx[0], idx[j], idx[j + 1]) for j in range(1, len(idx) - 1)]
            idx = idx[:3]
            break
    if len(idx) == 3:
        tris.append((idx[0], idx[1], idx[2]))
    return np.array(tris, dtype=np.intp).reshape(-1, 3)


def _flat(name: str, pts2: Array, z: float, up: bool) -> Patch:
    """The floor (up) or the ceiling (down, seen from below) polygon at height z."""
    tris = ear_clip(pts2)
    pts = np.column_stack([pts2, np.full(len(pts2), z)])
    if up:
        local = pts2.copy()
        normal = _EZ
    else:
        tris = tris[:, ::-1]
        local = pts2 * np.array([1.0, -1.0])  # x along +x, y along −y: not mirrored seen from below
        normal = -_EZ
    lo = local.min(axis=0)
    return Patch(name, pts, np.tile(normal, (len(pts), 1)), local - lo, local.max(axis=0) - lo, tris)


def _holed_face(name: str, origin: Array, d: Array, u_range: tuple[float, float], height: float,
                holes: list[tuple[float, float, float, float]], facing_out: bool) -> Patch:
    """A vertical rectangle origin + d u + z ẑ, u over u_range, z over [0, height], with
    rectangular holes (u0, u1, z0, z1), as the cells of the grid of every hole's sides. Its normal
    is d × ẑ (the wall's outward side) when ``facing_out``, else the opposite (into the room)."""
    lo, hi = u_range
    us = sorted({lo, hi, *(min(max(v, lo), hi) for h in holes for v in h[:2])})
    zs = sorted({0.0, height, *(min(max(v, 0.0), height) for h in holes for v in h[2:])})
    U, Z = np.meshgrid(us, zs, indexing="ij")  # (nu, nz)
    nu, nz = U.shape
    pts = origin[None, :] + U.reshape(-1, 1) * np.r_[d, 0.0][None, :] + Z.reshape(-1, 1) * _EZ[None, :]
    tris = []
    for i in range(nu - 1):
        for j in range(nz - 1):
            uc, zc = (us[i] + us[i + 1]) / 2, (zs[j] + zs[j + 1]) / 2
            if any(h[0] < uc < h[1] and h[2] < zc < h[3] for h in holes):
                continue
            a, b, c, e = i * nz + j, (i + 1) * nz + j, (i + 1) * nz + j + 1, i * nz + j + 1
            # Counter-clockwise in (u, z) faces d × ẑ (outward); reversed faces into the room.
            tris += [(a, b, c), (a, c, e)] if facing_out else [(a, c, b), (a, e, c)]
    normal = np.cross(np.r_[d, 0.0], _EZ) * (1.0 if facing_out else -1.0)
    # The chart's x runs to the right seen from the face's side: +u outside, −u inside.
    cu = U.reshape(-1) - lo if facing_out else hi - U.reshape(-1)
    chart = np.column_stack([cu, Z.reshape(-1)])
    return Patch(name, pts, np.tile(normal, (len(pts), 1)), chart, np.array([hi - lo, height]),
                 np.array(tris, dtype=np.intp).reshape(-1, 3))


def _reveal(name: str, a3: Array, d: Array, n: Array, t: float, width: float, z0: float, z1: float) -> Patch:
    """An opening's sill, start jamb, head and end jamb across the wall (depth 0 … t along n from
    the inner face), unrolled side by side in one chart (sill, start, head, end)."""
    d3, n3 = np.r_[d, 0.0], np.r_[n, 0.0]
    oh = z1 - z0

    def at(u: float, z: float, s: float) -> Array:
        return a3 + d3 * u + _EZ * z + n3 * s

    # Each quad counter-clockwise seen from the hole (its normal points into the opening).
    quads = [
        ([at(0, z0, 0), at(0, z0, t), at(width, z0, t), at(width, z0, 0)], [(0, 0), (0, t), (width, t), (width, 0)],
         _EZ),
        ([at(0, z0, 0), at(0, z1, 0), at(0, z1, t), at(0, z0, t)], [(0, 0), (oh, 0), (oh, t), (0, t)], d3),
        ([at(0, z1, 0), at(width, z1, 0), at(width, z1, t), at(0, z1, t)], [(0, 0), (width, 0), (width, t), (0, t)],
         -_EZ),
        ([at(width, z0, 0), at(width, z0, t), at(width, z1, t), at(width, z1, 0)], [(0, 0), (0, t), (oh, t), (oh, 0)],
         -d3),
    ]
    offsets = [0.0, width, width + oh, 2 * width + oh]
    pts, charts, normals, tris = [], [], [], []
    for k, ((corners, chart, normal), x0) in enumerate(zip(quads, offsets, strict=True)):
        pts += corners
        charts += [(x0 + cx, cy) for cx, cy in chart]
        normals += [normal] * 4
        tris += [(4 * k, 4 * k + 1, 4 * k + 2), (4 * k, 4 * k + 2, 4 * k + 3)]
    return Patch(name, np.array(pts, float), np.array(normals, float), np.array(charts, float),
                 np.array([2 * (width + oh), t]), np.array(tris, dtype=np.intp))


def room_patches(room: RoomShape, p: Array) -> list[Patch | None]:
    """Every logical face of ``room`` at params p, in the order floor, ceiling, wall{i}, outer{i},
    wtop{i}, then each opening's reveal; None for each face of a wall the room does not have."""
    w = room.walls(p)
    h = float(p[room.PARAMS.index("height")])
    t = float(p[room.PARAMS.index("thickness")])
    n = room.n_corners
    c = w["start"]
    out: list[Patch | None] = [_flat("floor", c, 0.0, True)]
    if room.ceiling:
        out.append(_flat("ceiling", c, h, False))
    holes: dict[int, list[tuple[float, float, float, float]]] = {i: [] for i in range(n)}
    for o in room.openings:
        off, width, oh, sill = (float(p[room.PARAMS.index(f"{o.name}_{s}")]) for s in ("offset", "width", "height",
                                                                                         "sill"))
        holes[o.wall].append((off, off + width, sill, sill + oh))
    there = room.walls_present  # an absent wall has no faces: neither textured nor an occluder
    for i in range(n):
        out.append(_holed_face(f"wall{i}", np.r_[c[i], 0.0], w["dir"][i], (0.0, float(w["length"][i])), h, holes[i],
                               False) if there[i] else None)
    for i in range(n):
        if not there[i]:
            out.append(None)
            continue
        start = np.r_[c[i] + t * w["normal"][i], 0.0]
        u0, u1 = (float(v) for v in w["outer_u"][i])
        out.append(_holed_face(f"outer{i}", start, w["dir"][i], (u0, u1), h, holes[i], True))
    if not room.ceiling:
        o_ = w["outer"]
        for i in range(n):
            j = (i + 1) % n
            quad = np.array([[*c[i], h], [*o_[i], h], [*o_[j], h], [*c[j], h]])
            out.append(polygon_patch(f"wtop{i}", quad, np.r_[w["dir"][i], 0.0]) if there[i] else None)
    for o in room.openings:
        off, width, oh, sill = (float(p[room.PARAMS.index(f"{o.name}_{s}")]) for s in ("offset", "width", "height",
                                                                                         "sill"))
        a3 = np.r_[c[o.wall] + w["dir"][o.wall] * off, 0.0]
        out.append(_reveal(f"{o.name}_reveal", a3, w["dir"][o.wall], w["normal"][o.wall], t, width, sill, sill + oh))
    return out
