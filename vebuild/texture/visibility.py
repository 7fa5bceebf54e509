"""Which faces a photo can see at all, known before the atlas is laid out (moderngl).

A face no photo can see, by the cameras' frusta and the model's own occlusion (a wall's back, its
top and ends, the underside of what rests on the floor), gets a token chart of
:data:`vebuild.texture.layout.TOKEN_TEXELS` a side instead of its full resolution: its texels would
all be filled anyway (its node's average colour, marked unseen), and full-sized they cost atlas
space, every full-page pass and merge, the PNGs, and every later load of the pages.

The test is exactly pass 2's precondition (:mod:`vebuild.texture`): a texel is seen only where its
face is one of the photo's :func:`faces_in_view` and holds the texel's pixel in the photo's ID
buffer. Here each photo's depth buffer is drawn as pass 1 draws it (the same program, vertices,
near and far planes, and for a lens the same pinhole cover), then each face in view not yet
known to be seen is drawn again with the depth test ``<=`` and no depth writes inside an
occlusion query: it passes wherever it is the nearest surface at a pixel centre (or ties the
nearest), so every face that holds a pixel of an ID buffer is counted, whatever the erosion, and
a face no query counts has no seen texel. A photo whose faces in view are all known seen is not
drawn.

From a camera inside a room, the faces wholly behind its walls (:mod:`vebuild.model.occlusion`) are
neither drawn into the depth buffer nor queried, here and in pass 1 (:func:`faces_not_hidden`):
they could not be the nearest surface at any pixel, so the buffer and the answers are the same
(but at one-pixel cracks in a room's mesh: see that module).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, depth_range, gl_projection, near_reach, view_matrix, world_to_camera
from vebuild.gl import load_program
from vebuild.gl.shaders import set_uniforms
from vebuild.model.occlusion import Rooms
from vebuild.texture.layout import SceneMesh
from vebuild.texture.lens import pinhole_cover

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FacePoints:
    """Every face's vertices and normals, grouped by face (for culling the faces a photo cannot
    see, all faces at once): face ``ids[k]`` has rows ``starts[k]`` up to the next start, and
    the bounding box ``lo[k]``, ``hi[k]``."""

    ids: NDArray[np.int64]
    starts: NDArray[np.int64]
    points: Array
    normals: Array
    lo: Array
    hi: Array


def face_points(mesh: SceneMesh) -> FacePoints:
    """Each face's vertices and normals (a face without a vertex is left out)."""
    order = np.argsort(mesh.face_of_vertex, kind="stable")
    ids = mesh.face_of_vertex[order]
    wanted = np.array([f.id for f in mesh.faces], np.int64)
    starts = np.searchsorted(ids, wanted, side="left")
    ends = np.searchsorted(ids, wanted, side="right")
    has = ends > starts
    kept = np.concatenate([order[a:b] for a, b in zip(starts[has], ends[has], strict=True)]) if has.any() else order[:0]
    counts = (ends - starts)[has]
    at = np.r_[0, np.cumsum(counts)[:-1]].astype(np.int64)
    P = np.asarray(mesh.vertices[kept], float)
    lo = np.minimum.reduceat(P, at) if len(at) else np.zeros((0, 3))
    hi = np.maximum.reduceat(P, at) if len(at) else np.zeros((0, 3))
    return FacePoints(wanted[has], at, P, np.asarray(mesh.normals[kept], float), lo, hi)


def faces_not_hidden(points: FacePoints, rooms: Rooms | None, cam: ImageCamera, near: float) -> set[int] | None:
    """The faces not wholly behind the walls of the room ``cam`` stands in (its near plane at
    ``near``; :mod:`vebuild.model.occlusion`); None where it stands in none: any may show."""
    if rooms is None or not rooms.shells or not len(points.ids):
        return None
    cover, _ = pinhole_cover(cam)
    seen = rooms.seen(np.asarray(cover.C, float), near_reach(cover.K, cover.width, cover.height, near), points.lo,
                      points.hi)
    return None if seen is None else {int(i) for i in points.ids[seen]}


def faces_in_view(points: FacePoints, cam: ImageCamera) -> set[int]:
    """Faces that may show in ``cam``: some vertex faces it and is in front, and their image
    bounds meet the image (for a photo with lens distortion, the pinhole image over its
    undistorted bounds: what the lens shows lies inside it)."""
    if not len(points.ids):
        return set()
    cam, _ = pinhole_cover(cam)
    P, N, at = points.points, points.normals, points.starts
    x = world_to_camera(cam.R, cam.C, P)
    front = x[:, 2] > 1e-6
    facing = np.einsum("ij,ij->i", N, cam.C - P) > 0
    keep = np.logical_or.reduceat(front, at) & np.logical_or.reduceat(facing, at)
    all_front = np.logical_and.reduceat(front, at)
    z = np.where(front, x[:, 2], 1.0)[:, None]  # the bounds below are used only where all are in front
    uv = x[:, :2] / z * [cam.K[0, 0], cam.K[1, 1]] + cam.K[:2, 2]
    outside = ((np.maximum.reduceat(uv[:, 0], at) < 0) | (np.maximum.reduceat(uv[:, 1], at) < 0)
               | (np.minimum.reduceat(uv[:, 0], at) > cam.width) | (np.minimum.reduceat(uv[:, 1], at) > cam.height))
    keep &= ~(all_front & outside)
    return {int(i) for i in points.ids[keep]}


class FaceQueries:
    """The triangles of ``mesh`` sorted by face, drawn one face at a time inside an occlusion query
    against the depth buffer of the framebuffer in use (drawn with the same program, vertices and
    matrices): which faces hold a pixel of it."""

    def __init__(self, ctx: moderngl.Context, prog: moderngl.Program, vbo: moderngl.Buffer, mesh: SceneMesh):
        self.ctx = ctx
        tri_face = mesh.triangle_faces
        order = np.argsort(tri_face, kind="stable")
        by_face = tri_face[order]
        fids = np.unique(by_face)
        first = np.searchsorted(by_face, fids, side="left")
        last = np.searchsorted(by_face, fids, side="right")
        self.runs = {int(f): (int(a), int(b - a)) for f, a, b in zip(fids, first, last, strict=True)}
        #: Whether the mesh lists its triangles face by face: then drawing some faces' runs in turn
        #: draws them in the mesh's order, and ties in the depth test go as drawing all would.
        self.in_mesh_order = bool(np.all(np.diff(tri_face) >= 0))
        self._ibo = ctx.buffer(mesh.triangles[order].astype("i4").tobytes())
        self._vao = ctx.vertex_array(prog, [(vbo, "3f 1f", "in_position", "in_face")], self._ibo)
        self._queries: list[moderngl.Query] = []

    def draw(self, faces: Iterable[int]) -> None:
        """Draw the triangles of ``faces`` (with the program's uniforms as set), in face order."""
        spans: list[list[int]] = []
        for start, count in sorted(self.runs[f] for f in set(faces) & self.runs.keys()):
            if spans and spans[-1][0] + spans[-1][1] == start:
                spans[-1][1] += count
            else:
                spans.append([start, count])
        for start, count in spans:
            self._vao.render(moderngl.TRIANGLES, vertices=3 * count, first=3 * start)

    def nearest(self, fbo: moderngl.Framebuffer, faces: Iterable[int]) -> set[int]:
        """Of ``faces``, those that pass the depth test ``<=`` somewhere in ``fbo`` (its depth
        buffer drawn by the caller, depth testing on): the nearest surface, or tied with it, at
        some pixel centre. Nothing is written: the depth and the colours stay as they were."""
        todo = sorted(set(faces) & self.runs.keys())
        if not todo:
            return set()
        ctx = self.ctx
        ctx.depth_func = "<="
        mask = fbo.color_mask  # () without colour attachments; one 4-tuple for one
        fbo.depth_mask = False
        if mask:  # the ID buffer's one attachment
            fbo.color_mask = (False, False, False, False)
        while len(self._queries) < len(todo):
            self._queries.append(ctx.query(samples=True))
        for fid, q in zip(todo, self._queries, strict=False):
            start, count = self.runs[fid]
            with q:
                self._vao.render(moderngl.TRIANGLES, vertices=3 * count, first=3 * start)
        if mask:
            fbo.color_mask = mask
        fbo.depth_mask = True
        ctx.depth_func = "<"
        return {fid for fid, q in zip(todo, self._queries, strict=False) if q.samples > 0}

    def release(self) -> None:
        # moderngl's queries hold no GL memory worth freeing one by one; they go with the context.
        self._vao.release()
        self._ibo.release()


def seen_faces(ctx: moderngl.Context, mesh: SceneMesh, cameras: Iterable[ImageCamera],
               points: FacePoints | None = None, rooms: Rooms | None = None) -> set[int]:
    """The ids of the faces of ``mesh`` that some camera's ID buffer holds (see the module's
    docstring); every other face has no texel any photo sees. ``rooms``: the model's rooms, whose
    walls hide what a camera inside one cannot see."""
    points = face_points(mesh) if points is None else points
    prog = load_program(ctx, "id")
    vbo = ctx.buffer(np.column_stack([mesh.vertices, mesh.face_of_vertex]).astype("f4").tobytes())
    ibo_all = ctx.buffer(mesh.triangles.astype("i4").tobytes())
    vao_all = ctx.vertex_array(prog, [(vbo, "3f 1f", "in_position", "in_face")], ibo_all)
    queries = FaceQueries(ctx, prog, vbo, mesh)
    seen: set[int] = set()
    depth: moderngl.Renderbuffer | None = None
    fbo: moderngl.Framebuffer | None = None
    try:
        for cam in cameras:
            todo = faces_in_view(points, cam) - seen
            if not todo & queries.runs.keys():
                continue
            cover, _ = pinhole_cover(cam)
            key = (cover.width, cover.height)
            if depth is None or depth.size != key:
                if fbo is not None:
                    fbo.release()
                if depth is not None:
                    depth.release()
                depth = ctx.depth_renderbuffer(key)
                fbo = ctx.framebuffer(depth_attachment=depth)
            assert fbo is not None
            near, far = depth_range(cover.R, cover.C, mesh.vertices)
            unhidden = faces_not_hidden(points, rooms, cam, near) if queries.in_mesh_order else None
            if unhidden is not None:
                todo &= unhidden
                if not todo:
                    continue
            V = view_matrix(cover.R, cover.C).astype("f4").T.copy()
            P = gl_projection(cover.K, cover.width, cover.height, near, far).astype("f4").T.copy()
            fbo.use()
            fbo.viewport = (0, 0, *key)
            fbo.clear(depth=1.0)
            ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = "<"
            fbo.depth_mask = True
            set_uniforms(prog, view=V, projection=P)
            if unhidden is None:
                vao_all.render(moderngl.TRIANGLES)
            else:
                queries.draw(unhidden)
            seen |= queries.nearest(fbo, todo)
            ctx.disable(moderngl.DEPTH_TEST)
    finally:
        queries.release()
        for obj in (vao_all, vbo, ibo_all, fbo, depth):
            if obj is not None:
                obj.release()
    return seen


def token_faces(mesh: SceneMesh, seen: Sequence[int] | set[int]) -> set[tuple[str, str]]:
    """(node, face) of each face of ``mesh`` not in ``seen``: those that get a token chart."""
    s = set(seen)
    return {(f.node, f.name) for f in mesh.faces if f.id not in s}
