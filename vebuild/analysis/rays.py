"""Exact ray and segment queries against the model's world mesh (numpy; the sight lines' and
trajectories' geometry).

Every triangle of the scene is tested with the Möller–Trumbore algorithm in float64, vectorised
over rays × triangles in chunks, with the triangles pruned to those whose bounding box meets the
bounding box of a chunk's segments. A ray that touches a triangle's edge or corner counts as a hit
(a grazing sight line is reported as blocked, the conservative answer). There is no GPU and no
sampling: a scene of a few thousand triangles answers tens of thousands of segments a second.

Tolerances: :data:`END_EPS_M` at each end of a segment, so that a point on a surface (a target
mark, a sample of an object's face, a bullet hole) is not hidden by its own surface.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.project.units import METRES, LengthUnit
from vebuild.render.scene import RenderScene

Array = NDArray[np.float64]

#: Length left out at each end of a segment (metres): surfaces this close to an end do not block it.
END_EPS_M = 1e-3
#: A point closer than this inside an object's surface is not inside it (metres).
INSIDE_MARGIN_M = 1e-3
#: Ray × triangle pairs per chunk (memory: about 40 float64 arrays of this size).
CHUNK_PAIRS = 200_000
#: Rays per chunk whose segments' bounding box prunes the triangles (give neighbouring rays together).
RAYS_PER_CHUNK = 256


@dataclass(frozen=True)
class Hit:
    """One crossing of a line with a surface: distance ``t`` along the line from its origin (m,
    signed), the world point, the node and its logical face, and the face's unit outward normal."""

    t: float
    point: Array
    node: str
    face: str
    normal: Array


class Occluders:
    """The scene's triangles, ready for ray queries."""

    def __init__(self, scene: RenderScene, unit: LengthUnit = METRES):
        """``unit``: the project's unit of lengths, for messages (:mod:`vebuild.project.units`)."""
        mesh = scene.mesh
        self.unit = unit
        V, T = np.asarray(mesh.vertices, float), np.asarray(mesh.triangles, np.intp)
        self.scene = scene
        self.v0 = V[T[:, 0]]
        self.e1 = V[T[:, 1]] - self.v0
        self.e2 = V[T[:, 2]] - self.v0
        n = np.cross(self.e1, self.e2)
        self.normal = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        self.area = 0.5 * np.linalg.norm(n, axis=1)
        P = V[T]
        self.lo, self.hi = P.min(axis=1), P.max(axis=1)
        self.face_id = np.asarray(mesh.triangle_faces, np.intp)  # 1-based
        self.node_names = scene.node_names
        self.node_of_tri = np.asarray(scene.node_of_face, np.intp)[self.face_id - 1]
        self.face_names = [f.name for f in mesh.faces]
        self._hulls: dict[str, Array | None] = {}

    # -- names ---------------------------------------------------------------------------------

    def node_of(self, tri: int) -> str:
        return self.node_names[int(self.node_of_tri[tri])]

    def face_of(self, tri: int) -> str:
        return self.face_names[int(self.face_id[tri]) - 1]

    def triangles_of(self, node: str) -> NDArray[np.intp]:
        """Indices of the triangles of ``node`` (empty if it has no faces)."""
        if node not in self.node_names:
            return np.zeros(0, np.intp)
        return np.flatnonzero(self.node_of_tri == self.node_names.index(node))

    def bounds(self) -> tuple[Array, Array]:
        return self.lo.min(axis=0), self.hi.max(axis=0)

    # -- solids --------------------------------------------------------------------------------

    def hull(self, node: str) -> Array | None:
        """Half-space equations (k, 4) of a node's convex hull (every primitive is convex), or None
        for a flat one (a quad), which has no inside."""
        if node not in self._hulls:
            from scipy.spatial import ConvexHull, QhullError  # imported at first use: docs/start-up.md

            tris = self.triangles_of(node)
            pts = np.concatenate([self.v0[tris], self.v0[tris] + self.e1[tris], self.v0[tris] + self.e2[tris]])
            try:
                self._hulls[node] = ConvexHull(pts).equations if len(pts) >= 4 else None
            except (QhullError, ValueError):
                self._hulls[node] = None
        return self._hulls[node]

    def inside(self, points: ArrayLike, margin: float = INSIDE_MARGIN_M) -> list[str | None]:
        """For each point (n, 3): the first node whose solid contains it by more than ``margin``, or None."""
        P = np.atleast_2d(np.asarray(points, float))
        out: list[str | None] = [None] * len(P)
        for node in self.node_names:
            eq = self.hull(node)
            if eq is None:
                continue
            d = P @ eq[:, :3].T + eq[:, 3]
            for i in np.flatnonzero(np.all(d < -margin, axis=1)):
                if out[i] is None:
                    out[i] = node
        return out

    # -- rays ----------------------------------------------------------------------------------

    def _candidates(self, lo: Array, hi: Array, exclude: NDArray[np.bool_] | None) -> NDArray[np.intp]:
        keep = np.all(self.hi >= lo - 1e-9, axis=1) & np.all(self.lo <= hi + 1e-9, axis=1)
        if exclude is not None:
            keep &= ~exclude
        return np.flatnonzero(keep)

    def _kernel(self, Org: Array, D: Array, tris: NDArray[np.intp], t_min: Array, t_max: Array) -> Array:
        """(n, k) hit distances of rays Org + t D (D need not be unit) on triangles ``tris``; inf where
        there is no hit in (t_min, t_max)."""
        v0, e1, e2 = self.v0[tris].T, self.e1[tris].T, self.e2[tris].T  # (3, k)
        Ox, Oy, Oz = (Org[:, i:i + 1] for i in range(3))
        Dx, Dy, Dz = (D[:, i:i + 1] for i in range(3))
        px = Dy * e2[2] - Dz * e2[1]
        py = Dz * e2[0] - Dx * e2[2]
        pz = Dx * e2[1] - Dy * e2[0]
        det = e1[0] * px + e1[1] * py + e1[2] * pz
        ok = np.abs(det) > 1e-15
        inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
        tx, ty, tz = Ox - v0[0], Oy - v0[1], Oz - v0[2]
        u = (tx * px + ty * py + tz * pz) * inv
        qx = ty * e1[2] - tz * e1[1]
        qy = tz * e1[0] - tx * e1[2]
        qz = tx * e1[1] - ty * e1[0]
        v = (Dx * qx + Dy * qy + Dz * qz) * inv
        t = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv
        tol = 1e-9
        hit = ok & (u >= -tol) & (v >= -tol) & (u + v <= 1.0 + tol) & (t > t_min[:, None]) & (t < t_max[:, None])
        return np.where(hit, t, np.inf)

    def first_hits(self, origins: ArrayLike, directions: ArrayLike, t_min: ArrayLike = 0.0,
                   t_max: ArrayLike = np.inf, exclude_nodes: Collection[str] = ()) -> tuple[Array, NDArray[np.intp]]:
        """The nearest hit of each ray in (t_min, t_max): distances (n,) in units of its direction's
        length (inf: none) and triangle indices (n,) (−1: none). Rays are taken in the order given;
        give neighbouring rays together (the chunks' bounding boxes prune the triangles)."""
        Org = np.atleast_2d(np.asarray(origins, float))
        D = np.atleast_2d(np.asarray(directions, float))
        n = len(Org)
        t0 = np.broadcast_to(np.asarray(t_min, float), (n,))
        t1 = np.broadcast_to(np.asarray(t_max, float), (n,))
        best = np.full(n, np.inf)
        tri = np.full(n, -1, np.intp)
        excl = None
        if exclude_nodes:
            idx = [self.node_names.index(x) for x in exclude_nodes if x in self.node_names]
            excl = np.isin(self.node_of_tri, idx)
        finite = np.isfinite(t1)
        for i in range(0, n, RAYS_PER_CHUNK):
            sl = slice(i, min(n, i + RAYS_PER_CHUNK))
            if finite[sl].all():  # prune to the triangles that the chunk's segments' box meets
                ends = np.concatenate([Org[sl] + D[sl] * t0[sl, None], Org[sl] + D[sl] * t1[sl, None]])
                cand = self._candidates(ends.min(axis=0), ends.max(axis=0), excl)
            else:
                cand = self._candidates(np.full(3, -np.inf), np.full(3, np.inf), excl)
            m = sl.stop - sl.start
            step = max(1, CHUNK_PAIRS // m)
            for a in range(0, len(cand), step):
                c = cand[a:a + step]
                t = self._kernel(Org[sl], D[sl], c, t0[sl], t1[sl])
                k = np.argmin(t, axis=1)
                tk = t[np.arange(m), k]
                better = tk < best[sl]
                best[sl] = np.where(better, tk, best[sl])
                tri[sl] = np.where(better, c[k], tri[sl])
        return best, tri

    def segments_blocked(self, starts: ArrayLike, ends: ArrayLike, end_eps: float = END_EPS_M,
                         exclude_nodes: Collection[str] = ()) -> tuple[NDArray[np.bool_], Array, NDArray[np.intp]]:
        """Whether each segment start→end crosses a surface more than ``end_eps`` from either end:
        (blocked (n,), distance of the first crossing from the start in metres (inf: none),
        triangle (−1: none))."""
        P0 = np.atleast_2d(np.asarray(starts, float))
        P1 = np.atleast_2d(np.asarray(ends, float))
        P0, P1 = np.broadcast_arrays(P0, P1)
        L = np.linalg.norm(P1 - P0, axis=1)
        D = (P1 - P0) / np.maximum(L, 1e-300)[:, None]
        t, tri = self.first_hits(P0, D, end_eps, np.maximum(L - end_eps, end_eps), exclude_nodes)
        return np.isfinite(t), t, tri

    def line_hits(self, origin: ArrayLike, direction: ArrayLike) -> list[Hit]:
        """Every crossing of the infinite line origin + t·direction (unit) with a surface, in order
        of t (negative: behind the origin). A crossing on an edge shared by two triangles of one
        face, or by faces of one node at one point, is listed once."""
        Org = np.asarray(origin, float)[None]
        d = np.asarray(direction, float)
        d = d / np.linalg.norm(d)
        t = self._kernel(Org, d[None], np.arange(len(self.v0)), np.array([-np.inf]), np.array([np.inf]))[0]
        order = [int(i) for i in np.argsort(t) if np.isfinite(t[i])]
        out: list[Hit] = []
        for i in order:
            node = self.node_of(i)
            if out and out[-1].node == node and abs(out[-1].t - t[i]) < 1e-7:
                continue
            out.append(Hit(float(t[i]), Org[0] + t[i] * d, node, self.face_of(i), self.normal[i].copy()))
        return out

    def exit_distance(self, origin: ArrayLike, direction: ArrayLike, margin: float = 0.0) -> float:
        """Distance along a unit direction at which a ray from ``origin`` leaves the scene's bounding
        box (grown by ``margin``); 0 if the origin is outside it and the ray never enters."""
        lo, hi = self.bounds()
        lo, hi = lo - margin, hi + margin
        Org, d = np.asarray(origin, float), np.asarray(direction, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lo - Org) / d, (hi - Org) / d
        t_far = np.where(d != 0, np.maximum(ta, tb), np.inf)
        t_near = np.where(d != 0, np.minimum(ta, tb), -np.inf)
        inside_axes = (d != 0) | ((Org >= lo) & (Org <= hi))
        if not inside_axes.all() or np.max(t_near) > np.min(t_far):
            return 0.0
        return float(max(0.0, np.min(t_far)))
