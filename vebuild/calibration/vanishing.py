"""Best-fit vanishing points from directed image segments (paper §2, Figure 2).

A vanishing point is kept as a homogeneous 3-vector ``v`` (pixels; ``v[2] == 0`` at infinity),
optimised on the unit sphere in a normalised image frame, so a frontal wall whose lines are
parallel in the image is an ordinary point of the parameter space and not an error.

The residual of a segment is the paper's: the orthogonal distance of its end points to the line
that joins the vanishing point to the segment's midpoint (both end points lie at the same
distance on either side; one signed value is kept per segment).

A vanishing segment may also be a *polyline* ``[u1, v1, u2, v2, ..., un, vn]`` (n ≥ 2 points along
one straight edge, directed first → last): its middle points say how straight the edge is in the
photo, which is what lens distortion is estimated from (:mod:`.photo`). Its residuals generalise
the paper's: every point's distance to the line joining the vanishing point to the points'
centroid (for two points, the centroid is the midpoint). The vanishing point fit here uses a
polyline's end points only (:func:`end_segments`), a pinhole start for the joint solve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.determinism import deterministic
from vebuild.errors import CalibrationError

from .lsq import photo_numeric_failures

Array = NDArray[np.float64]

#: Shorter segments than this (pixels) are taken for slips of the mouse, not for edges.
MIN_SEGMENT_LENGTH_PX = 2.0
#: Two segments whose end points are all within this distance (pixels) of one another's line
#: lie on one image line: together they say nothing about where the vanishing point is.
COLLINEAR_TOLERANCE_PX = 1.5


@dataclass(frozen=True)
class VanishingPointFit:
    """A vanishing point fitted to the segments of one axis.

    point : (3,) homogeneous pixel coordinates, unit norm in the normalised frame; w == 0 at infinity.
    residuals_px : (n,) signed distance of each segment's end points to its fitted line.
    """

    point: Array
    residuals_px: Array

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_px**2)))

    def finite_point(self) -> Array | None:
        """(u, v) when the point is finite, else None."""
        w = self.point[2]
        return None if abs(w) < 1e-12 else self.point[:2] / w


def normalising_transform(width: float, height: float) -> Array:
    """N with p̃ = N p: image centre at 0, longer half-side at 1 (conditions the fits)."""
    s = 2.0 / max(width, height)
    return np.array([[s, 0.0, -s * width / 2], [0.0, s, -s * height / 2], [0.0, 0.0, 1.0]])


def homogeneous(p: ArrayLike) -> Array:
    """(..., 2) → (..., 3) with a trailing 1."""
    p = np.asarray(p, float)
    return np.concatenate([p, np.ones(p.shape[:-1] + (1,))], axis=-1)


def segment_residuals(v: ArrayLike, segments: ArrayLike) -> Array:
    """Signed distance (pixels) of each segment's first end point to the line midpoint–v.

    Parameters
    ----------
    v : (3,) homogeneous vanishing point in pixel coordinates (any scale; w may be 0).
    segments : (n, 4) rows u1, v1, u2, v2.
    """
    seg = np.asarray(segments, float)
    p1 = homogeneous(seg[:, 0:2])
    m = homogeneous(0.5 * (seg[:, 0:2] + seg[:, 2:4]))
    lines = np.cross(m, np.asarray(v, float)[None, :])
    norm = np.hypot(lines[:, 0], lines[:, 1])
    return np.einsum("ij,ij->i", lines, p1) / np.maximum(norm, 1e-300)


def as_polylines(segments: ArrayLike | list, axis: str, photo: str) -> list[Array]:
    """One axis' vanishing segments as a list of (m, 2) point arrays (m ≥ 2), checked.

    Accepts an (n, 4) array (today's segments), an (n, 2m) array, or a list of flat rows of
    different even lengths ``[u1, v1, ..., um, vm]``. Raises CalibrationError for a row that is
    not pairs of numbers, fewer than two points, fewer than two segments, end points closer than
    MIN_SEGMENT_LENGTH_PX, or segments that all lie on one image line.
    """
    if isinstance(segments, np.ndarray) and segments.dtype != object:
        rows = list(segments.reshape(-1, 4)) if segments.ndim == 1 else list(segments)
    else:
        rows = [np.asarray(r, float).reshape(-1) for r in segments]  # type: ignore[union-attr]
    polys = []
    for k, r in enumerate(rows):
        r = np.asarray(r, float).reshape(-1)
        if r.size < 4 or r.size % 2:
            raise CalibrationError(
                photo, f"axis {axis}, segment {k}: expected [u1, v1, u2, v2, ...] (two points or more, "
                f"pixels), got {r.size} number{'s' if r.size != 1 else ''}")
        polys.append(r.reshape(-1, 2))
    check_segments(end_segments(polys), axis, photo)
    for k, p in enumerate(polys):
        if not np.all(np.isfinite(p)):
            raise CalibrationError(photo, f"axis {axis}: segment {k} has a coordinate that is not a number")
    return polys


def end_segments(polylines: list[Array]) -> Array:
    """(n, 4) first and last points u1, v1, un, vn of each polyline."""
    if not polylines:
        return np.zeros((0, 4))
    return np.array([np.r_[p[0], p[-1]] for p in polylines], float).reshape(-1, 4)


def check_segments(segments: ArrayLike, axis: str, photo: str) -> Array:
    """Validate one axis' segments and return them as an (n, 4) float array.

    Raises CalibrationError for fewer than two segments, a zero-length segment, or segments that
    all lie on one image line.
    """
    seg = np.asarray(segments, float).reshape(-1, 4)
    if len(seg) < 2:
        raise CalibrationError(
            photo,
            f"axis {axis} has {len(seg)} vanishing segment{'s' if len(seg) != 1 else ''}; "
            "a vanishing point needs at least two, along different edges",
        )
    if not np.all(np.isfinite(seg)):
        raise CalibrationError(photo, f"axis {axis}: a vanishing segment has a coordinate that is not a number")
    lengths = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    for k in np.flatnonzero(lengths < MIN_SEGMENT_LENGTH_PX):
        raise CalibrationError(
            photo,
            f"axis {axis}, segment {k}: its end points are {lengths[k]:.2f} px apart; "
            f"expected a segment at least {MIN_SEGMENT_LENGTH_PX:g} px long along an edge",
        )
    if _all_collinear(seg):
        raise CalibrationError(
            photo,
            f"axis {axis}: all {len(seg)} segments lie on one image line (coincident), so they do not "
            "fix a vanishing point; mark segments along different parallel edges",
        )
    return seg


def _all_collinear(seg: Array) -> bool:
    p1, p2 = seg[:, 0:2], seg[:, 2:4]
    d = p2[0] - p1[0]
    n = np.array([-d[1], d[0]]) / np.hypot(*d)
    dist = np.abs(np.concatenate([(p1 - p1[0]) @ n, (p2 - p1[0]) @ n]))
    return bool(np.all(dist < COLLINEAR_TOLERANCE_PX))


def initial_vanishing_point(segments: Array, width: float, height: float) -> Array:
    """Algebraic estimate: the point nearest all segment lines (smallest singular vector).

    Returned in normalised homogeneous coordinates, unit norm.
    """
    N = normalising_transform(width, height)
    p1 = homogeneous(segments[:, 0:2]) @ N.T
    p2 = homogeneous(segments[:, 2:4]) @ N.T
    lines = np.cross(p1, p2)
    # Unit (a, b) makes each row a signed distance; weighting by length trusts long edges more.
    lines /= np.hypot(lines[:, 0], lines[:, 1])[:, None]
    lengths = np.hypot(*(p2[:, :2] - p1[:, :2]).T)
    _, _, Vt = np.linalg.svd(lines * lengths[:, None])
    return Vt[-1] / np.linalg.norm(Vt[-1])


def tangent_basis(x: Array) -> tuple[Array, Array]:
    """Two unit vectors orthogonal to the unit vector x and to each other."""
    a = np.eye(3)[np.argmin(np.abs(x))]
    t1 = np.cross(x, a)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(x, t1)


@deterministic
@photo_numeric_failures("the fit of a vanishing point", "check that axis' segments (straight edges along it, "
                        "of some length, not all through one point)")
def fit_vanishing_point(
    segments: ArrayLike, width: float, height: float, *, axis: str = "?", photo: str = "photo"
) -> VanishingPointFit:
    """Best-fit vanishing point of ≥ 2 segments (paper §2), handling points at infinity.

    Non-linear least squares over the unit sphere of normalised homogeneous points, each step
    re-parameterised in the tangent plane at the current estimate.
    """
    from scipy.optimize import least_squares  # imported at first use: docs/start-up.md

    seg = check_segments(segments, axis, photo)
    N = normalising_transform(width, height)
    N_inv = np.linalg.inv(N)
    x0 = initial_vanishing_point(seg, width, height)
    t1, t2 = tangent_basis(x0)

    def point(ab: Array) -> Array:
        x = x0 + ab[0] * t1 + ab[1] * t2
        return x / np.linalg.norm(x)

    def residuals(ab: Array) -> Array:
        return segment_residuals(N_inv @ point(ab), seg)

    sol = least_squares(residuals, np.zeros(2), method="lm", x_scale=1.0)
    x = point(sol.x)
    v = N_inv @ x
    return VanishingPointFit(point=v / np.linalg.norm(N @ v), residuals_px=residuals(sol.x))
