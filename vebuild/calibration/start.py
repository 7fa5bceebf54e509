"""Where a joint placement starts (:mod:`vebuild.calibration.positions`): the first photo at the
origin marker's ray (or another marker's, where that start cannot place every photo), each further
photo from a baseline to a placed photo or by resection from the markers placed so far, the markers
triangulated from the photos that see them. Rays leave each camera through its lens distortion
(vebuild/camera.py)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import Lens, pixel_rays_world
from vebuild.errors import CalibrationError

if TYPE_CHECKING:
    from .placement_types import PhotoInput

Array = NDArray[np.float64]

#: Lines meeting at a smaller angle than this (degrees) do not fix a point along them well enough
#: to start from (with 1 px clicks at f ≈ 1500 px a 2° parallax leaves ~2 % depth error).
MIN_INTERSECTION_ANGLE_DEG = 2.0
#: The origin's rays from the photos that see it may meet at this smaller angle (degrees) where no
#: start from the origin itself places every photo: its depth along them is then held by the
#: refinement, not by them.
ORIGIN_MIN_ANGLE_DEG = 0.2


def intersect_lines(points: Array, dirs: Array) -> Array:
    """The point nearest, in least squares, to the lines pᵢ + t dᵢ (dᵢ unit), shape (3,)."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for p, d in zip(points, dirs, strict=True):
        M = np.eye(3) - np.outer(d, d)
        A += M
        b += M @ p
    return np.asarray(np.linalg.solve(A, b), float)


def _max_angle_deg(dirs: Array) -> float:
    c = np.clip(np.abs(dirs @ dirs.T), -1.0, 1.0)
    return float(np.degrees(np.arccos(c.min())))


def unit_baseline(rays_j: Array, rays_k: Array) -> Array:
    """Unit baseline B̂ from camera j to camera k from shared-marker rays (eqs. 5–7).

    The smallest eigenvector of Γ = Σ (M̂ⱼ × M̂ₖ)(M̂ⱼ × M̂ₖ)ᵀ, signed so that the markers lie in
    front of both cameras: X = Cⱼ + a M̂ⱼ = Cₖ + b M̂ₖ with a, b > 0.
    """
    Cc = np.cross(rays_j, rays_k)
    Gamma = Cc.T @ Cc
    _, vecs = np.linalg.eigh(Gamma)
    B = vecs[:, 0]
    votes = 0.0
    for mj, mk in zip(rays_j, rays_k, strict=True):
        ab, *_ = np.linalg.lstsq(np.column_stack([mj, -mk]), B, rcond=None)
        votes += np.sign(ab[0]) + np.sign(ab[1])
    return B if votes >= 0 else -B


def _rays(p: PhotoInput, names: Sequence[str]) -> Array:
    return pixel_rays_world(p.K, p.R, np.array([p.markers[n] for n in names]), Lens(p.k1, p.k2))


def initial_positions(
    photos: Sequence[PhotoInput], origin: str, known: Mapping[str, Array]
) -> tuple[dict[str, Array], dict[str, Array]]:
    """Unit-scale positions by the paper's construction, then triangulation and resection.

    The construction starts at the origin marker's ray from the photo that sees the most markers
    with it. Where that start leaves photos it cannot place (two photos alone see the origin and
    their baseline nearly meets it: its line and the baseline do not cross), it starts again from
    each other marker in turn, most seen first, until one start places every photo; the origin is
    then triangulated from the photos that see it, even at less than MIN_INTERSECTION_ANGLE_DEG
    (down to ORIGIN_MIN_ANGLE_DEG: the refinement then fixes its depth from everything else), and
    the result moved so that the origin is at zero. Only where the start lies changes, not what
    is solved from it."""
    C, X, pending = _construct(photos, origin)
    if pending:
        seen = {n: sum(n in p.markers for p in photos) for p in photos for n in p.markers}
        for anchor in sorted((n for n in seen if n != origin and seen[n] >= 2), key=lambda n: (-seen[n], n)):
            C2, X2, left = _construct(photos, anchor)
            o = X2.get(origin)
            if not left and o is None:
                obs = [p for p in photos if origin in p.markers and p.id in C2]
                rays = np.array([_rays(p, [origin])[0] for p in obs])
                if len(obs) >= 2 and _max_angle_deg(rays) >= ORIGIN_MIN_ANGLE_DEG:
                    o = intersect_lines(np.array([C2[p.id] for p in obs]), rays)
            if not left and o is not None:
                C, X, pending = {k: v - o for k, v in C2.items()}, {k: v - o for k, v in X2.items()}, []
                X[origin] = np.zeros(3)
                break
    if pending:
        p = pending[0]
        n_known = sum(1 for n in p.markers if n in X)
        raise CalibrationError(
            p.id,
            f"the camera cannot be placed: it sees {n_known} marker(s) whose position is known from "
            "other photos and does not share two markers with a placed photo; mark at least two "
            "markers that other photos also show (or, to place it alone, give it a scale of its own, a "
            "camera_height or a known length, and mark the origin marker in it)",
        )
    return C, X


def _construct(photos: Sequence[PhotoInput], anchor: str) -> tuple[dict[str, Array], dict[str, Array],
                                                                   list[PhotoInput]]:
    """The construction from marker ``anchor`` at zero, the first photo (the one that sees the
    most markers with it) at unit distance along its ray: the cameras and markers it places and
    the photos it cannot place."""
    with_anchor = [p for p in photos if anchor in p.markers]
    first = max(with_anchor, key=lambda p: len(p.markers))
    C: dict[str, Array] = {first.id: -_rays(first, [anchor])[0]}
    X: dict[str, Array] = {anchor: np.zeros(3)}
    # Known positions are metric while the start is unit-scale: they join after scaling.
    pending = [p for p in photos if p.id != first.id]
    while pending:
        for p in pending:
            placed = _place_by_baseline(p, C, X, photos)
            if placed is None:
                placed = _resect(p, X)
            if placed is not None:
                C[p.id] = placed
                pending.remove(p)
                _triangulate_all(photos, C, X)
                break
        else:
            break
    _triangulate_all(photos, C, X)
    return C, X, pending


def _place_by_baseline(p: PhotoInput, C: Mapping[str, Array], X: Mapping[str, Array],
                       photos: Sequence[PhotoInput]) -> Array | None:
    """Figure 4: meet the line from a placed marker back along p's ray with the baseline line.

    The paper's placed marker is the origin; any marker already placed serves the same way, so a
    photo without the origin is placed as soon as it shares two markers with a placed photo and
    sees one placed marker.
    """
    best = None
    for q in photos:
        if q.id not in C:
            continue
        shared = sorted(set(p.markers) & set(q.markers))
        if len(shared) >= 2 and (best is None or len(shared) > len(best[1])):
            best = (q, shared)
    if best is None:
        return None
    q, shared = best
    B = unit_baseline(_rays(q, shared), _rays(p, shared))
    anchors = [n for n in sorted(p.markers) if n in X]
    if not anchors:
        return None
    t_all = -_rays(p, anchors)
    # The anchor whose line meets the baseline at the widest angle fixes the position best.
    k = int(np.argmin(np.abs(t_all @ B)))
    t, anchor = t_all[k], X[anchors[k]]
    if np.degrees(np.arccos(min(1.0, abs(float(B @ t))))) < MIN_INTERSECTION_ANGLE_DEG:
        return None  # marker, camera j and camera k in a line: the two lines do not meet
    # Line 1: anchor + s t (s > 0); line 2: C_q + r B.
    (s, r), *_ = np.linalg.lstsq(np.column_stack([t, -B]), C[q.id] - anchor, rcond=None)
    if s <= 0:
        return None
    return 0.5 * (anchor + s * t + C[q.id] + r * B)


def _resect(p: PhotoInput, X: Mapping[str, Array]) -> Array | None:
    """Camera centre from ≥ 2 markers of known position, K and R known."""
    names = [n for n in sorted(p.markers) if n in X]
    if len(names) < 2:
        return None
    rays = _rays(p, names)
    if _max_angle_deg(rays) < MIN_INTERSECTION_ANGLE_DEG:
        return None
    return intersect_lines(np.array([X[n] for n in names]), rays)


def _triangulate_all(photos: Sequence[PhotoInput], C: Mapping[str, Array], X: dict[str, Array]) -> None:
    names = sorted({n for p in photos for n in p.markers})
    for n in names:
        if n in X:
            continue
        obs = [p for p in photos if n in p.markers and p.id in C]
        if len(obs) < 2:
            continue
        rays = np.array([_rays(p, [n])[0] for p in obs])
        if _max_angle_deg(rays) < MIN_INTERSECTION_ANGLE_DEG:
            continue
        X[n] = intersect_lines(np.array([C[p.id] for p in obs]), rays)
