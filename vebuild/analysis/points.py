"""Points written as text and points picked in a photo or a view (:data:`POINT_SYNTAX`):

- a handle, ``node:handle`` (a box's corner ``cabinet:v4``);
- a point on a face of a primitive, ``node@face:s,t``: s, t metres from the face's centre along
  the face's x and y axes (a restable face's frame, as for ``rests_on``; on a side face x runs
  horizontally, to the right seen from outside, and y up the face); ``node@face`` is its centre;
- a pixel of a photo or a named view, ``photo:ID@u,v`` or ``view:NAME@u,v``: the first surface of
  the model that the pixel's ray meets (pixel convention of DESIGN.md: u right, v down, origin at
  the image's top-left corner);
- a marker's name (``T2``).

Each is a :class:`~vebuild.analysis.solved.Point` tied to the model. Layer 6 of DESIGN.md: numpy
only (a pixel's ray is intersected with the primitives' meshes here rather than through the
renderer's ID buffer).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import PINHOLE, Lens, pixel_rays_world
from vebuild.errors import VebuildError
from vebuild.model.primitives import Primitive, Sphere, _Round
from vebuild.model.scene import ModelError

from .solved import MeasureError, Point, SolvedModel, to_coords

Array = NDArray[np.float64]

#: Facets around curved surfaces when a pixel's ray is intersected with the model.
PICK_SEGMENTS = 32
POINT_SYNTAX = ("node:handle, node@face:s,t (metres from the face's centre), node@face, photo:ID@u,v, "
                "view:NAME@u,v, or a marker's name")



def find_node(solved: SolvedModel, name: str):
    try:
        return solved.model.node(name)
    except ModelError:
        known = ", ".join(n.name for n in solved.model.nodes)
        raise MeasureError(f"no node named '{name}' in the model; the nodes are: {known}") from None


def _primitive_node(solved: SolvedModel, name: str, label: str):
    n = find_node(solved, name)
    if n.primitive is None:
        parts = ", ".join(c for c in solved.model.subtree(name)[1:] if solved.model.node(c).primitive is not None)
        raise MeasureError(f"point '{label}': node '{name}' is a group with no surface of its own; name one of its "
                           f"parts ({parts or 'none'})")
    return n


def _numbers(text: str, label: str, what: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise MeasureError(f"point '{label}': expected {what} as two numbers 'A,B', got '{text}'") from None
    if not (np.isfinite(a) and np.isfinite(b)):
        raise MeasureError(f"point '{label}': {what} must be finite, got '{text}'")
    return a, b


def parse_point(text: str, solved: SolvedModel, cameras: Mapping[str, Any] | None = None,
                resolve_camera: Callable[[str, str], Any] | None = None) -> Point:
    """A point from its written form (see the module, and ``POINT_SYNTAX``).

    ``resolve_camera(kind, name)`` returns the :class:`~vebuild.camera.ImageCamera` of a photo
    (kind ``photo``) or a named view (kind ``view``) for pixel points.
    """
    text = text.strip()
    head = text.split(":", 1)[0]
    if head in ("photo", "view") and ":" in text and "@" in text.split(":", 1)[1]:
        name, uv = text.split(":", 1)[1].rsplit("@", 1)
        u, v = _numbers(uv, text, "a pixel u,v")
        if resolve_camera is None:
            raise MeasureError(f"point '{text}': pixel points need the project's cameras")
        try:
            cam = resolve_camera(head, name)
        except VebuildError as e:
            raise MeasureError(f"point '{text}': {e}") from None
        if not (0 <= u <= cam.width and 0 <= v <= cam.height):
            raise MeasureError(f"point '{text}': pixel ({u:g}, {v:g}) lies outside the {head}'s "
                               f"{cam.width}×{cam.height} image")
        return pick(solved, cam.K, cam.R, cam.C, (u, v), text, cam.lens)
    if "@" in text:
        node, rest = text.split("@", 1)
        face, _, st = rest.partition(":")
        s, t = _numbers(st, text, "face coordinates s,t (metres)") if st else (0.0, 0.0)
        return face_point(solved, node, face, s, t, text)
    if ":" in text:
        node, handle = text.rsplit(":", 1)
        prim = _primitive_node(solved, node, text).primitive
        if handle not in prim.handle_names():
            raise MeasureError(f"point '{text}': node '{node}' ({prim.TYPE}) has no handle '{handle}'; its handles "
                               f"are: {', '.join(prim.handle_names())}")
        return Point(text, "handle", node=node, handle=handle)
    if text in solved.marker_col:
        return Point(text, "marker", marker=text)
    raise MeasureError(f"point '{text}' is not a marker of the calibration; write a point as {POINT_SYNTAX}")


def _face_triangles(prim: Primitive, face: str, label: str) -> tuple[Any, Array]:
    mesh = prim.mesh(segments=PICK_SEGMENTS)
    if face not in mesh.face_names:
        raise MeasureError(f"point '{label}': a {prim.TYPE} has no face '{face}'; its faces are: "
                           f"{', '.join(mesh.face_names)}")
    fid = mesh.face_names.index(face) + 1
    return mesh, mesh.faces[mesh.face_ids == fid]


def _is_curved(prim: Primitive, face: str) -> bool:
    return (isinstance(prim, _Round) and face == "side") or isinstance(prim, Sphere)


def face_point(solved: SolvedModel, node: str, face: str, s: float, t: float, label: str | None = None) -> Point:
    """The point s, t metres from the centre of a flat ``face`` of ``node`` along the face's axes."""
    label = label or f"{node}@{face}:{s:g},{t:g}"
    prim = _primitive_node(solved, node, label).primitive
    mesh, tris = _face_triangles(prim, face, label)
    if _is_curved(prim, face):
        raise MeasureError(f"point '{label}': face '{face}' of a {prim.TYPE} is curved; give a handle or a pixel "
                           "of a photo instead of face coordinates")
    V = mesh.vertices
    if face in prim.faces():
        o, x, y, n = prim.face_frame(face)
    else:
        used = np.unique(tris)
        o = V[used].mean(axis=0)
        n = np.cross(V[tris[0, 1]] - V[tris[0, 0]], V[tris[0, 2]] - V[tris[0, 0]])
        n /= np.linalg.norm(n)
        x = np.cross([0.0, 0.0, 1.0], n)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
        y = np.cross(n, x)
    p = o + s * x + t * y
    if not _in_triangles(p, V, tris):
        size = mesh.chart_size_m[mesh.face_names.index(face)]
        u = solved.unit.symbol
        raise MeasureError(f"point '{label}': ({s:g}, {t:g}) {u} from the centre of face '{face}' of '{node}' lies "
                           f"off that face ({size[0]:.3f} × {size[1]:.3f} {u})")
    return Point(label, "surface", node=node, face=face, coords=tuple(float(c) for c in to_coords(prim, p)))


def _in_triangles(p: Array, V: Array, tris: Array, tol: float = 1e-9) -> bool:
    a, b, c = V[tris[:, 0]], V[tris[:, 1]], V[tris[:, 2]]
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return bool(np.any((v >= -tol) & (w >= -tol) & (v + w <= 1 + tol)))


def ray_hit(solved: SolvedModel, origin: Array, direction: Array) -> tuple[str, str, Array] | None:
    """The first surface a ray meets: (node, face name, world point), or None (Möller–Trumbore over
    every primitive's mesh, both sides of each triangle)."""
    xm, T = solved._state(solved.x0)
    best: tuple[float, str, str, Array] | None = None
    o, d = np.asarray(origin, float), np.asarray(direction, float)
    for node in solved.model.nodes:
        if node.primitive is None:
            continue
        mesh = node.primitive.mesh(segments=PICK_SEGMENTS)
        W = mesh.vertices @ T[node.name][:3, :3].T + T[node.name][:3, 3]
        a, b, c = W[mesh.faces[:, 0]], W[mesh.faces[:, 1]], W[mesh.faces[:, 2]]
        e1, e2 = b - a, c - a
        pv = np.cross(d, e2)
        det = (e1 * pv).sum(1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        sv = o - a
        u = (sv * pv).sum(1) * inv
        qv = np.cross(sv, e1)
        v = (qv @ d) * inv
        t = (qv * e2).sum(1) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
        if np.any(hit):
            k = np.flatnonzero(hit)[np.argmin(t[hit])]
            if best is None or t[k] < best[0]:
                best = (float(t[k]), node.name, mesh.face_names[mesh.face_ids[k] - 1], o + t[k] * d)
    return None if best is None else best[1:]


def pick(solved: SolvedModel, K: Array, R: Array, C: Array, uv: Sequence[float], label: str,
         lens: Lens = PINHOLE) -> Point:
    """The point of the model seen at pixel ``uv`` by the camera K, R, C with lens distortion ``lens``
    (the pixel as the lens put it, undistorted onto its ray); an error if its ray meets nothing."""
    d = pixel_rays_world(K, R, np.asarray(uv, float), lens)
    hit = ray_hit(solved, np.asarray(C, float), d)
    if hit is None:
        raise MeasureError(f"point '{label}': the ray through pixel ({uv[0]:g}, {uv[1]:g}) meets no surface of the "
                           "model (it leaves through an opening or misses every object); pick a pixel on a surface")
    node, face, X = hit
    _, T = solved._state(solved.x0)
    inv = np.linalg.inv(T[node])
    local = inv[:3, :3] @ X + inv[:3, 3]
    prim = solved.model.node(node).primitive
    assert prim is not None  # the ray met one of its faces
    coords = to_coords(prim, local, snap_face=face if _is_curved(prim, face) else None)
    return Point(label, "surface", node=node, face=face, coords=tuple(float(c) for c in coords))


def face_plane_points(solved: SolvedModel, node: str, face: str) -> list[Point]:
    """Three points of a flat face, tied to it (for a plane that moves with the parameters)."""
    label = f"{node}@{face}"
    prim = _primitive_node(solved, node, label).primitive
    mesh, tris = _face_triangles(prim, face, label)
    if _is_curved(prim, face):
        raise MeasureError(f"'{label}': face '{face}' of a {prim.TYPE} is curved; a height is measured above a flat "
                           "face")
    return [Point(label, "surface", node=node, face=face, coords=tuple(float(c) for c in to_coords(prim, p)))
            for p in mesh.vertices[tris[0]]]
