"""The scene's triangles in drawing order, per frame: back faces culled, front to back.

On software OpenGL every fragment that passes the depth test is shaded, so what is drawn first
decides how much is shaded. :class:`DrawOrder` keeps the scene's triangles in blocks, one per
(atlas page, node, culled or not), and gives for each view an index array and its draw ranges:

- Back faces of closed primitives (box, wedge, cylinder, frustum, sphere: their triangles are
  counter-clockwise seen from outside, :class:`vebuild.texture.layout.SceneMesh`) are culled: from
  outside such a primitive, each of its back faces lies behind one of its front faces, so culling
  them changes no pixel. Quads and rooms (seen from both sides), and any triangle whose winding
  disagrees with its normals, stay double-sided. When the camera, or its near plane, may be inside
  a closed primitive (its bounding box grown by the near plane's reach), nothing is culled.
- Within a page, blocks are drawn nearest first (by the distance from the camera to their
  bounding boxes), so that the depth test rejects hidden fragments before they are shaded.
- Blocks whose bounding boxes lie wholly outside one of the view's four side planes are not
  drawn: they could not give a fragment (on software OpenGL their vertices cost time all the same).
- From a camera inside a room, blocks wholly behind its walls, floor and ceiling (seen through
  none of its openings) are not drawn either (:mod:`vebuild.model.occlusion`).

The ID buffer, the shadow maps and every other pass draw all triangles in the mesh's order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.model.occlusion import rooms_of
from vebuild.render.scene import RenderScene

Array = NDArray[np.float64]

#: Primitive types whose surfaces are closed and oriented outwards (culled from outside).
CLOSED_TYPES = frozenset({"box", "wedge", "cylinder", "frustum", "sphere"})


@dataclass(frozen=True)
class Range:
    """One draw: atlas page, back faces culled or not, first index and index count."""

    page: int
    cull: bool
    first: int
    count: int


class DrawOrder:
    """The triangles of ``scene`` in blocks (see the module's docstring); ``tri_page`` is each
    triangle's atlas page."""

    def __init__(self, scene: RenderScene, tri_page: NDArray[np.int32]):
        mesh = scene.mesh
        tris = mesh.triangles.astype(np.int64)
        n = len(tris)
        node_of_face = scene.node_of_face
        tri_face = mesh.face_of_vertex[tris[:, 0]] - 1 if n else np.zeros(0, np.int64)
        tri_node = node_of_face[tri_face] if n else np.zeros(0, np.int32)
        kinds = {node.name: node.primitive.TYPE for node in scene.model.nodes if node.primitive is not None}
        closed = np.array([kinds.get(name) in CLOSED_TYPES for name in scene.node_names], bool)
        cull = closed[tri_node] if n else np.zeros(0, bool)
        if n:
            P = mesh.vertices[tris]
            g = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
            cull &= np.einsum("ij,ij->i", g, mesh.normals[tris].sum(axis=1)) > 0.0
        self.closed_nodes = closed
        # Blocks: triangles sorted by (page, double-sided after culled, node), stable.
        order = np.lexsort((tri_node, ~cull, tri_page)) if n else np.zeros(0, np.int64)
        self.index = tris[order].astype("i4")
        key = np.stack([tri_page[order], ~cull[order], tri_node[order]], axis=1) if n else np.zeros((0, 3), int)
        starts = np.flatnonzero(np.r_[True, (np.diff(key, axis=0) != 0).any(axis=1)]) if n else np.zeros(0, int)
        self.starts, self.counts = starts, np.diff(np.r_[starts, n])
        self.block_page = key[starts, 0].astype(int)
        self.block_cull = ~key[starts, 1].astype(bool)
        self.block_node = key[starts, 2].astype(int)
        corners = mesh.vertices[self.index].reshape(-1, 3) if n else np.zeros((0, 3))
        first = 3 * starts
        self.lo = np.minimum.reduceat(corners, first, axis=0) if n else np.zeros((0, 3))
        self.hi = np.maximum.reduceat(corners, first, axis=0) if n else np.zeros((0, 3))
        self.rooms = rooms_of(scene.model)
        self._last: tuple[tuple[int, ...], bool] | None = None

    def may_be_inside(self, C: Array, reach: float) -> bool:
        """Whether a point within ``reach`` of ``C`` may lie inside a closed primitive."""
        m = self.block_cull
        if not m.any():
            return False
        return bool(np.all((self.lo[m] - reach <= C) & (C <= self.hi[m] + reach), axis=1).any())

    def plan(self, C: Array, reach: float, planes: Array | None = None,
             rooms: bool = True) -> tuple[NDArray[np.int32] | None, list[Range]]:
        """For a camera at ``C`` whose near plane reaches ``reach`` from it: the index array to
        draw (None: the same as the last call's) and the draws over it. ``planes`` (k, 3): the
        normals m of the view's side planes, the view being where m · (X − C) ≥ 0 for each
        (:func:`side_planes`); None: no block is left out for lying outside the view (those behind
        the walls of the room the camera is in still are); ``rooms``: whether those are."""
        cull_ok = not self.may_be_inside(C, reach)
        dist = np.linalg.norm(np.maximum(np.maximum(self.lo - C, C - self.hi), 0.0), axis=1)
        cull = self.block_cull & cull_ok
        order = np.lexsort((dist, ~cull, self.block_page))
        if planes is not None and len(order):  # each box's corner furthest along each normal
            far = np.where(planes[None] > 0, self.hi[:, None], self.lo[:, None]) - C  # (blocks, k, 3)
            scale = np.abs(self.hi - C).max(axis=1) + np.abs(self.lo - C).max(axis=1)
            inside = (np.einsum("bkj,kj->bk", far, planes) >= -1e-9 * scale[:, None]).all(axis=1)
            order = order[inside[order]]
        seen = self.rooms.seen(C, reach, self.lo[order], self.hi[order]) if rooms and len(order) else None
        if seen is not None:
            order = order[seen]
        key = (tuple(order.tolist()), cull_ok)
        index = None
        if key != self._last:
            self._last = key
            parts = [self.index[s:s + c] for s, c in zip(self.starts[order], self.counts[order], strict=True)]
            index = np.concatenate(parts) if parts else np.zeros((0, 3), "i4")
        ranges: list[Range] = []
        at = 0
        for b in order:
            page, c, count = int(self.block_page[b]), bool(cull[b]), 3 * int(self.counts[b])
            if ranges and ranges[-1].page == page and ranges[-1].cull == c:
                last = ranges[-1]
                ranges[-1] = Range(page, c, last.first, last.count + count)
            else:
                ranges.append(Range(page, c, at, count))
            at += count
        return index, ranges


def side_planes(K: Array, R: Array, width: int, height: int) -> Array:
    """(4, 3): world normals of a camera's four side planes through its centre (:meth:`DrawOrder.plan`).

    In camera coordinates a point x (z > 0) is in view when 0 ≤ u·z ≤ width·z and 0 ≤ v·z ≤
    height·z, with (u·z, v·z, z) = K x: four half-spaces n · x ≥ 0 through the centre."""
    K = np.asarray(K, float)
    n = np.array([K[0], width * K[2] - K[0], K[1], height * K[2] - K[1]])
    return n @ np.asarray(R, float)
