"""Footprints of the model's objects and 2-D collision tests (pure numpy).

Walking and dragging happen over the floor, so each primitive is represented by its footprint: the
convex hull of its vertices projected onto the floor plane (z = 0), with the height range it
occupies. A box's footprint is exact; a cylinder's is its 32-gon; anything concave (an L-shaped
desk) is conservative. Two things collide when their height ranges overlap and their footprints
overlap by more than a tolerance.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

from vebuild.model.scene import Model

Array = NDArray[np.float64]

#: Facets around curved primitives for footprints (fewer than the renderer's: a footprint is a bound).
SEGMENTS = 16
#: Thickness given to a footprint that has none (a vertical quad seen from above is a segment).
MIN_THICKNESS_M = 0.01


@dataclass(frozen=True)
class Footprint:
    """A node's footprint: ``hull`` (k, 2) counter-clockwise, and the heights ``z_lo``–``z_hi`` it spans."""

    node: str
    hull: Array
    z_lo: float
    z_hi: float


def convex_hull_2d(points: Array) -> Array:
    """Counter-clockwise convex hull of 2-D points; a segment or point gets MIN_THICKNESS_M width."""
    points = np.asarray(points, float)
    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        # Degenerate: all points on a line (a wall quad seen from above). Widen it.
        c = points.mean(axis=0)
        d = points - c
        _, _, vt = np.linalg.svd(d, full_matrices=False) if len(points) > 1 else (None, None, np.eye(2))
        u = vt[0]
        n = np.array([-u[1], u[0]])
        s = d @ u
        a, b = c + s.min() * u, c + s.max() * u
        h = 0.5 * MIN_THICKNESS_M
        return np.array([a - h * n, b - h * n, b + h * n, a + h * n])


def local_vertices(model: Model) -> dict[str, Array]:
    """Each primitive node's vertices in its own frame (they do not change when joints move)."""
    return {n.name: n.primitive.mesh(None, SEGMENTS).vertices for n in model.nodes if n.primitive is not None}


def footprints(model: Model, transforms: Mapping[str, Array] | None = None, nodes: Collection[str] | None = None,
               local: Mapping[str, Array] | None = None) -> list[Footprint]:
    """Footprints of the primitive nodes (all, or those named) at ``transforms`` (default: the
    model's world transforms); ``local`` caches :func:`local_vertices`."""
    transforms = transforms if transforms is not None else model.world_transforms()
    local = local if local is not None else local_vertices(model)
    out = []
    for name, V in local.items():
        if nodes is not None and name not in nodes:
            continue
        T = transforms[name]
        W = V @ T[:3, :3].T + T[:3, 3]
        out.append(Footprint(name, convex_hull_2d(W[:, :2]), float(W[:, 2].min()), float(W[:, 2].max())))
    return out


def circle_push(centre: Array, radius: float, hull: Array) -> Array:
    """The smallest 2-D move that takes a circle out of a convex polygon (zero if they do not meet)."""
    c = np.asarray(centre, float)
    a, b = hull, np.roll(hull, -1, axis=0)
    e = b - a
    t = np.clip(np.einsum("ij,ij->i", c - a, e) / np.maximum(np.einsum("ij,ij->i", e, e), 1e-18), 0.0, 1.0)
    closest = a + t[:, None] * e
    dist = np.linalg.norm(c - closest, axis=1)
    k = int(np.argmin(dist))
    normals = np.stack([e[:, 1], -e[:, 0]], axis=1) / np.maximum(np.linalg.norm(e, axis=1), 1e-18)[:, None]
    inside = np.all(np.einsum("ij,ij->i", c - a, normals) <= 0.0)  # counter-clockwise: outward normals
    if inside:
        # Out through the nearest edge, then a radius further.
        depth = -np.einsum("ij,ij->i", c - a, normals)
        j = int(np.argmin(depth))
        return normals[j] * (depth[j] + radius)
    if dist[k] >= radius:
        return np.zeros(2)
    return (c - closest[k]) / max(dist[k], 1e-12) * (radius - dist[k])


def overlap_depth(a: Array, b: Array) -> float:
    """How far two convex polygons overlap (separating-axis theorem): the smallest projection
    overlap over both polygons' edge normals; ≤ 0 when they are apart."""
    depth = np.inf
    for poly in (a, b):
        e = np.roll(poly, -1, axis=0) - poly
        n = np.stack([e[:, 1], -e[:, 0]], axis=1)
        n = n / np.maximum(np.linalg.norm(n, axis=1), 1e-18)[:, None]
        pa, pb = a @ n.T, b @ n.T
        ov = np.minimum(pa.max(axis=0), pb.max(axis=0)) - np.maximum(pa.min(axis=0), pb.min(axis=0))
        depth = min(depth, float(ov.min()))
        if depth <= 0:
            return depth
    return depth


def z_overlap(a: Footprint, lo: float, hi: float) -> bool:
    return a.z_hi > lo and a.z_lo < hi
