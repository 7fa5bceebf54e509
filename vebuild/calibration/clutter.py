"""Which detected edges are clutter, and whether a grouped direction rests on enough.

Pure functions over detected segments (numpy); no project, no I/O. Used by the grouping of
``vebuild detect`` (vebuild.actions.detect) before and after :func:`.lines.group_manhattan`.

**Short edges** (:func:`short`): under :data:`MIN_GROUP_LENGTH_REL` of the longer side, they
are not grouped (below).

**Texture** (:func:`textured`). The edges of a building run in three directions, so that the
edges near any one of them, in the image, lie along at most three orientations (their vanishing
points'). Cobblestones, foliage, gravel and leaves make many short edges turned every way. An
edge is texture where the edges whose midpoints lie within :data:`TEXTURE_RADIUS_REL` of the
photo's longer side of its own number :data:`TEXTURE_MIN_EDGES` or more and fewer than
:data:`TEXTURE_MODES_SHARE` of them lie within ±:data:`TEXTURE_MODE_HALF_DEG` of the three
orientations most of them share. An edge longer than :data:`TEXTURE_KEEP_LENGTH_REL` of the
longer side is never texture (a pilaster beside a tree).

**Curves** (:func:`curved`). A detected edge is written as a polyline of four points (the
centroids of its edge points in four stretches, each with its 1σ across the line). After the
grouping's undistortion, the two middle points' distances to the chord through the two end
points, in units of their 1σ, form a χ² with 2 degrees of freedom; an edge whose χ² exceeds
:data:`CURVE_CHI2` (p = 0.001) bends more than its noise and the lens allow: a sagging wire, a
branch, an arch. It is not grouped.

**A weak direction** (:func:`weak_direction`; vebuild.actions.detect_checks applies it to the
weakest of three grouped axes only). A grouped axis is proposed only if its segments,
fitted alone, fix its vanishing direction: the direction's 1σ on the sphere (through the
grouping's focal length, each segment weighted by its measured 1σ) is at most
:data:`WEAK_DIRECTION_MAX_SIGMA_DEG`, :data:`WEAK_MIN_LONG` of them at least are
:data:`WEAK_LONG_REL` of the longer side long or more, they meet their own best-fit point within
their 1σ (χ², n − 2 degrees of freedom, :data:`WEAK_CHI2_P`), and the direction lies within
:data:`WEAK_ORTHOGONAL_SIGMAS` of its σ (and :data:`WEAK_ORTHOGONAL_MIN_DEG` at least) of the
direction orthogonal to the two other axes' (the frame's, for the grouping's f; the σ includes
the turn a principal point 3 % off the centre gives, :data:`.priors.PRINCIPAL_POINT_SIGMA_REL`,
since the frame puts it at the centre). Otherwise the
message says why, and the axis is not proposed: a photo then keeps the two directions that its
edges do fix, and the calibration takes its focal length from EXIF, with EXIF's σ.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Edges shorter than this share of the photo's longer side are not grouped: a short edge agrees
#: with any vanishing point within a wide angle (the grouping's inlier test: its ends within 1.5 px
#: per 2000 px of a line through the point), so that cobbles and leaves near the horizon, turned
#: every way but foreshortened to nearly level, outvote a building's edges.
MIN_GROUP_LENGTH_REL = 0.035
#: Neighbourhood of an edge, as a share of the photo's longer side (radius about its midpoint).
TEXTURE_RADIUS_REL = 0.05
#: Fewest edges (the edge itself included) in a neighbourhood for it to be texture.
TEXTURE_MIN_EDGES = 8
#: A neighbourhood is a building's where at least this share of its edges lie along three
#: orientations.
TEXTURE_MODES_SHARE = 0.75
#: Half-width of an orientation shared by a neighbourhood's edges, degrees.
TEXTURE_MODE_HALF_DEG = 6.0
#: An edge at least this long (share of the longer side) is never texture.
TEXTURE_KEEP_LENGTH_REL = 0.12
#: χ², 2 degrees of freedom, p = 0.001: a polyline's middle points this far off its chord bend.
CURVE_CHI2 = 13.8
#: A direction whose 1σ exceeds this (degrees, on the sphere) is weak.
WEAK_DIRECTION_MAX_SIGMA_DEG = 1.5
#: A direction with fewer than WEAK_MIN_LONG segments of WEAK_LONG_REL of the longer side is weak: a
#: building's direction shows some long edges; one made of short edges only (cobbles, reveals,
#: leaves) fixes little, and any clutter in it weighs as much as its true edges.
WEAK_MIN_LONG = 2
WEAK_LONG_REL = 0.05
#: A direction whose segments miss their own best-fit vanishing point by more than their 1σ allows
#: (χ² of their ends' distances, n − 2 degrees of freedom, beyond this p) is not one direction:
#: long clutter edges (a trunk, a railing, a kerb) that happen to meet near one point.
WEAK_CHI2_P = 0.001
#: A third direction further than this many σ from the two others' orthogonal one is not theirs ...
WEAK_ORTHOGONAL_SIGMAS = 4.0
#: ... and further than this many degrees at least.
WEAK_ORTHOGONAL_MIN_DEG = 1.0


def _orientation_deg(segs: Array) -> Array:
    d = segs[:, 2:] - segs[:, :2]
    return np.asarray(np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180.0, float)


def short(segments: Array, width: int, height: int) -> NDArray[np.bool_]:
    """Which segments (n, 4) are too short to group (:data:`MIN_GROUP_LENGTH_REL`)."""
    length = np.hypot(*(segments[:, 2:] - segments[:, :2]).T)
    return np.asarray(length < MIN_GROUP_LENGTH_REL * max(width, height), bool)


def textured(segments: Array, width: int, height: int) -> NDArray[np.bool_]:
    """Which segments (n, 4) lie in texture (module docstring)."""
    n = len(segments)
    out = np.zeros(n, bool)
    if n < TEXTURE_MIN_EDGES:
        return out
    side = float(max(width, height))
    mid = 0.5 * (segments[:, :2] + segments[:, 2:])
    length = np.hypot(*(segments[:, 2:] - segments[:, :2]).T)
    theta = _orientation_deg(segments)
    r2 = (TEXTURE_RADIUS_REL * side) ** 2
    for i in range(n):
        if length[i] >= TEXTURE_KEEP_LENGTH_REL * side:
            continue
        near = np.flatnonzero(np.sum((mid - mid[i]) ** 2, axis=1) <= r2)
        if len(near) < TEXTURE_MIN_EDGES:
            continue
        t = theta[near]
        diff = np.abs(t[:, None] - t[None, :])
        close = np.minimum(diff, 180.0 - diff) <= TEXTURE_MODE_HALF_DEG  # (k, k)
        left = np.ones(len(t), bool)
        for _ in range(3):
            counts = close[:, left].sum(axis=1)
            k = int(np.argmax(counts))
            if counts[k] == 0:
                break
            left &= ~close[k]
        out[i] = (1.0 - left.sum() / len(t)) < TEXTURE_MODES_SHARE
    return out


def curved(polylines: Array, sigma_px: Array, K: Array, k1: float) -> NDArray[np.bool_]:
    """Which polylines (n, 8), four points each, bend beyond their 1σ (n,) once undistorted by
    K and k1 (module docstring)."""
    from vebuild.camera import Lens, undistort_pixels

    n = len(polylines)
    if n == 0:
        return np.zeros(0, bool)
    P = polylines.reshape(n, -1, 2)
    if k1 != 0.0:
        P = undistort_pixels(K, P.reshape(-1, 2), Lens(k1)).reshape(P.shape)
    a, b = P[:, 0], P[:, -1]
    d = b - a
    nrm = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    off = np.sum((P[:, 1:-1] - a[:, None]) * nrm[:, None], axis=2)  # (n, m − 2)
    # The chord's own end points carry the same noise: a middle point's offset from the chord has
    # about 1.25 (two points' share) times its variance; σ floors already hold the lens's residual.
    chi2 = np.sum(off**2, axis=1) / (1.25 * np.maximum(sigma_px, 1e-6) ** 2)
    return np.asarray(chi2 > CURVE_CHI2, bool)


def direction_sigma_deg(segs: Array, sigma_px: Array, f: float, c: Array) -> tuple[Array, float]:
    """The unit direction (3,), camera frame, of the vanishing point the segments (n, 4) share,
    and its 1σ in degrees (the larger axis of its error ellipse on the sphere): least squares on
    the planes through the camera and each segment, each end point weighted by its 1σ."""
    p1 = np.c_[(segs[:, :2] - c) / f, np.ones(len(segs))]
    p2 = np.c_[(segs[:, 2:] - c) / f, np.ones(len(segs))]
    nrm = np.cross(p1, p2)
    L = np.linalg.norm(segs[:, 2:] - segs[:, :2], axis=1)
    # A plane's normal turns by about √2 σ / L (radians) about the segment for an end point's σ.
    s_ang = np.sqrt(2.0) * np.maximum(sigma_px, 1e-6) / np.maximum(L, 1e-9)
    nu = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    A = nu / s_ang[:, None]
    _, sv, vt = np.linalg.svd(A, full_matrices=False)
    d = vt[-1]
    if len(sv) < 3 or sv[1] <= 0:
        return d, 180.0
    return d, float(np.degrees(1.0 / sv[1]))


def weak_direction(segs: Array, sigma_px: Array, f: float, c: Array, side: float,
                   frame_direction: Array | None) -> str | None:
    """Why an axis' segments (n, 4, undistorted) do not fix their vanishing direction, or None
    where they do (module docstring). ``frame_direction``: the grouping's direction (3,) for the
    axis, square to the two others', or None where they are not both proposed."""
    from .priors import PRINCIPAL_POINT_SIGMA_REL

    length = np.linalg.norm(segs[:, 2:] - segs[:, :2], axis=1)
    n_long = int(np.sum(length >= WEAK_LONG_REL * side))
    if n_long < WEAK_MIN_LONG:
        return (f"{n_long} of its {len(segs)} segments are {WEAK_LONG_REL:.0%} of the photo's longer side long "
                f"({WEAK_LONG_REL * side:.0f} px) or more, under {WEAK_MIN_LONG}: short edges only")
    d, s = direction_sigma_deg(segs, sigma_px, f, c)
    if len(segs) > 2:
        from scipy.stats import chi2

        from .lines import _distances

        K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
        x2 = float(np.sum((_distances(segs, (K @ d)[:, None])[:, 0] / np.maximum(sigma_px, 1e-6)) ** 2))
        limit = float(chi2.ppf(1.0 - WEAK_CHI2_P, len(segs) - 2))
        if x2 > limit:
            return (f"its {len(segs)} segments miss the point they best meet at by more than their 1σ allows "
                    f"(χ² {x2:.0f} > {limit:.0f}, {len(segs) - 2} degrees of freedom, p = {WEAK_CHI2_P}): "
                    "edges of clutter meeting near one point")
    if s > WEAK_DIRECTION_MAX_SIGMA_DEG:
        return (f"its {len(segs)} segments fix its vanishing direction to {s:.1f}° (1σ; nearly parallel in the "
                f"image, or short), more than {WEAK_DIRECTION_MAX_SIGMA_DEG}°")
    if frame_direction is not None:
        off = float(np.degrees(np.arccos(min(1.0, abs(float(d @ frame_direction))))))
        # The frame puts the principal point at the centre: the true one's offset turns it too.
        s_pp = float(np.degrees(PRINCIPAL_POINT_SIGMA_REL * side / f))
        tol = max(WEAK_ORTHOGONAL_SIGMAS * float(np.hypot(s, s_pp)), WEAK_ORTHOGONAL_MIN_DEG)
        if off > tol:
            return (f"its segments meet {off:.1f}° from the direction square to the two others, more than "
                    f"{tol:.1f}° (4σ of its fit and of the principal point's offset): not the building's third "
                    "direction (a slope, clutter)")
    return None
