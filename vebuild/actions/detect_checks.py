"""The checks ``vebuild detect`` makes on a photo's grouped axes before it proposes them: an axis
whose segments are pieces of one image line, whose vanishing point coincides with another axis',
or whose segments do not fix its direction (vebuild.calibration.clutter.weak_direction) is not
proposed. Used by :func:`vebuild.actions.detect.orient_proposals`.
"""

from __future__ import annotations

from itertools import combinations
from typing import TYPE_CHECKING

import numpy as np

from vebuild.calibration.clutter import direction_sigma_deg, weak_direction
from vebuild.calibration.photo import SAME_VANISHING_POINT_DEG
from vebuild.calibration.vanishing import COLLINEAR_TOLERANCE_PX, fit_vanishing_point, normalising_transform
from vebuild.camera import AXES, intrinsic_matrix
from vebuild.errors import VebuildError

if TYPE_CHECKING:
    from .detect_types import SegmentProposal


def weak_axes(segs: np.ndarray, sigma_px: np.ndarray, chosen: dict[str, np.ndarray], D: np.ndarray, f: float,
              c: np.ndarray, side: float) -> dict[str, str]:
    """The third direction that is not proposed, and why: where three axes were grouped (columns
    of D: world x, y, z in the camera; ``chosen``: each one's segments, indices into ``segs``,
    undistorted), the one whose segments fix its vanishing direction least (the largest 1σ),
    where they do not fix it (vebuild.calibration.clutter.weak_direction). Two axes are always kept: they fix the
    rotation, and the calibration then takes f from EXIF, with EXIF's σ."""
    if not all(len(chosen[a]) for a in AXES):
        return {}
    sig = {a: direction_sigma_deg(segs[chosen[a]], sigma_px[chosen[a]], f, c)[1] for a in AXES}
    a = max(AXES, key=lambda b: sig[b])  # the third direction: the one its segments fix least
    idx = chosen[a]
    why = weak_direction(segs[idx], sigma_px[idx], f, c, side, D[:, AXES.index(a)])
    return {} if why is None else {a: why}


def drop_same_point(props: list[SegmentProposal], counts: dict[str, int], D: np.ndarray, f: float,
                     c: np.ndarray, w: int, h: int) -> None:
    """Drop the smaller of two axes whose vanishing points coincide in the image (within
    SAME_VANISHING_POINT_DEG on the sphere of normalised points: the calibration's refusal of
    a mislabelled set; a strong lens bends one direction's edges into two such sets). Both the
    frame's points and the points fitted to each axis' written segments alone (as the
    calibration fits them, end points as the lens put them) are compared."""
    N = normalising_transform(w, h)
    K = intrinsic_matrix(f, *c)
    unit = {a: (N @ K @ D[:, k]) / np.linalg.norm(N @ K @ D[:, k]) for k, a in enumerate(AXES)}
    own: dict[str, np.ndarray | None] = {}
    for a in AXES:
        ends = np.array([np.r_[q.points[:2], q.points[-2:]] for q in props if q.axis == a]).reshape(-1, 4)
        try:
            x = N @ fit_vanishing_point(ends, w, h, axis=a).point if counts[a] else None
            own[a] = x / np.linalg.norm(x) if x is not None else None
        except VebuildError:
            own[a] = None

    def apart(x: np.ndarray | None, y: np.ndarray | None) -> float:
        return 180.0 if x is None or y is None else float(np.degrees(np.arccos(min(1.0, abs(float(x @ y))))))

    for a, b in combinations([a for a in AXES if counts[a]], 2):
        if counts[a] and counts[b] and min(apart(unit[a], unit[b]), apart(own[a], own[b])) \
                < SAME_VANISHING_POINT_DEG:
            weaker = a if counts[a] < counts[b] else b
            props[:] = [p for p in props if p.axis != weaker]
            counts[weaker] = 0


def one_image_line(segs: np.ndarray, side: int) -> bool:
    """Whether all segments lie on one image line: what the calibration refuses for an axis
    (within COLLINEAR_TOLERANCE_PX; ``side`` is unused, kept for the call's shape)."""
    if len(segs) == 0:
        return False
    a, b = segs[0, :2], segs[0, 2:]
    n = np.array([a[1] - b[1], b[0] - a[0]]) / max(float(np.linalg.norm(b - a)), 1e-9)
    d = np.abs(np.r_[(segs[:, :2] - a) @ n, (segs[:, 2:] - a) @ n])
    return bool(np.all(d < COLLINEAR_TOLERANCE_PX))


