"""A primitive's textured triangle mesh: its logical faces as flat or revolved patches, joined into
one mesh with a packed texture atlas (each chart its face's size in metres, so one density of
texels per metre serves every face). :mod:`.primitives` describes each type's faces.

Layer 1 (DESIGN.md): numpy only; no GL, no file I/O.
"""

from __future__ import annotations

import dataclasses
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Gutter between atlas charts, in texels when a density is given (enough for bilinear filtering
#: and a couple of mip levels without bleeding between faces).
GUTTER_TEXELS = 4
#: Gutter as a fraction of √(total chart area) when no density is given.
GUTTER_FRACTION = 1.0 / 128.0



@dataclass(frozen=True)
class Mesh:
    """A primitive's triangle mesh with a texture atlas; vertices are duplicated along face borders.

    Attributes
    ----------
    vertices : (n, 3) float64, local frame, metres.
    faces : (m, 3) int32, counter-clockwise seen from outside (outward normals).
    face_ids : (m,) int32, the 1-based logical face of each triangle (0 is "nothing" in GPU buffers).
    face_names : list of F names; ``face_names[i - 1]`` names logical face i.
    normals : (n, 3) float64 unit outward normals (per face on flat faces, smooth on curved ones).
    uv : (n, 2) float64 texture coordinates in [0, 1]²: u along a face's x axis, v along its y axis;
        (0, 0) is the start of the texture's first row in memory, so texel (i, j) of an N×N
        texture covers [i/N, (i+1)/N) × [j/N, (j+1)/N).
    chart_size_m : (F, 2) float64 width and height in metres of each logical face's chart.
    chart_uv : (F, 4) float64 each chart's rectangle (u0, v0, u1, v1) in the atlas; charts do not
        overlap and are separated by a gutter.
    atlas_size_m : the side of the square atlas in metres: an N×N texture with
        N = atlas_size_m × texels_per_metre gives that density on every face (an integer N when
        ``mesh`` was given ``texels_per_metre``: charts then start on texel boundaries).
    """

    vertices: Array
    faces: NDArray[np.int32]
    face_ids: NDArray[np.int32]
    face_names: list[str]
    normals: Array
    uv: Array
    chart_size_m: Array
    chart_uv: Array
    atlas_size_m: float


@dataclass(frozen=True)
class Patch:
    """One logical face before packing: its own vertices and chart coordinates in metres."""

    name: str
    points: Array  # (v, 3)
    normals: Array  # (v, 3)
    chart: Array  # (v, 2) metres from the chart's lower-left corner
    size: Array  # (2,) chart width, height in metres
    triangles: NDArray[np.intp]  # (t, 3) into points, counter-clockwise seen from outside


def polygon_patch(name: str, corners: Array, x_axis: Array | None = None) -> Patch | None:
    """A flat convex polygon, corners (k, 3) counter-clockwise seen from outside.

    Repeated consecutive corners are dropped (a wedge is a box whose top front edge has collapsed
    onto its bottom front edge); None when fewer than three remain. The chart's x axis is
    ``x_axis`` or the first edge's direction, its y axis normal × x, so side faces stand upright.
    """
    kept: list[Array] = []
    for c in corners:
        if not kept or not np.array_equal(c, kept[-1]):
            kept.append(c)
    if len(kept) > 1 and np.array_equal(kept[-1], kept[0]):
        kept.pop()
    if len(kept) < 3:
        return None
    pts = np.array(kept)
    k = len(pts)
    normal = np.cross(pts, np.roll(pts, -1, axis=0)).sum(axis=0)  # Newell's method
    normal /= np.linalg.norm(normal)
    x = pts[1] - pts[0] if x_axis is None else np.asarray(x_axis, float)
    x = x - (x @ normal) * normal
    x /= np.linalg.norm(x)
    y = np.cross(normal, x)
    if k > 4:  # a disc: fan from its centre rather than from one corner (no slivers)
        pts = np.vstack([pts, pts.mean(axis=0)])
        tris = np.array([[k, i, (i + 1) % k] for i in range(k)])
    else:
        tris = np.array([[0, i, i + 1] for i in range(1, k - 1)])
    local = pts @ np.stack([x, y]).T
    lo = local.min(axis=0)
    return Patch(name, pts, np.tile(normal, (len(pts), 1)), local - lo, local.max(axis=0) - lo, tris)


def circle(segments: int) -> tuple[Array, Array, Array]:
    """Angles 0…2π at segments + 1 points and their cos, sin; the last point is the first, exactly."""
    theta = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    c, s = np.cos(theta), np.sin(theta)
    c[-1], s[-1] = c[0], s[0]  # the seam's two copies must coincide bit for bit to close the mesh
    return theta, c, s


def revolution_patch(name: str, radius: Array, z: Array, n_r: Array, n_z: Array, segments: int) -> Patch:
    """A surface of revolution about +z from a profile of rows bottom to top.

    radius, z : (rows,) the profile; n_r, n_z : (rows,) its outward unit normal in the (r, z) plane.
    The grid has segments + 1 columns (the seam is duplicated so u runs 0…1). The chart is
    2π·max(radius) wide and as tall as the profile's length, so no part of the surface gets fewer
    texels per metre than the nominal density (smaller rims and the sphere's high latitudes get more).
    """
    theta, c, s = circle(segments)
    rows, cols = len(radius), segments + 1
    pts = np.stack(np.broadcast_arrays(radius[:, None] * c, radius[:, None] * s, z[:, None]), axis=-1)
    nrm = np.stack(np.broadcast_arrays(n_r[:, None] * c, n_r[:, None] * s, n_z[:, None]), axis=-1)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(radius), np.diff(z)))])
    width = 2.0 * np.pi * radius.max()
    chart = np.stack(np.broadcast_arrays(theta / (2.0 * np.pi) * width, arc[:, None]), axis=-1)
    # Quad (j, i) → (j, i+1) → (j+1, i+1) → (j+1, i) runs counter-clockwise seen from outside.
    a = (np.arange(rows - 1)[:, None] * cols + np.arange(segments)).ravel()
    tris = np.concatenate([np.stack([a, a + 1, a + cols + 1], 1), np.stack([a, a + cols + 1, a + cols], 1)])
    return Patch(name, pts.reshape(-1, 3), nrm.reshape(-1, 3), chart.reshape(-1, 2), np.array([width, arc[-1]]),
                  tris)


def _pack(sizes: Array, texels_per_metre: float | None) -> tuple[Array, float]:
    """Shelf-pack charts (F, 2) into a square; returns their lower-left corners (F, 2) and the side.

    Tallest charts first, rows about √(total area) wide. With a density every corner is snapped up
    to a texel boundary and the side to a whole number of texels.
    """
    if texels_per_metre is None:
        gutter = GUTTER_FRACTION * np.sqrt(np.prod(sizes, axis=1).sum())

        def snap(v: float) -> float:
            return v
    else:
        gutter = GUTTER_TEXELS / texels_per_metre

        def snap(v: float) -> float:
            return float(np.ceil(v * texels_per_metre - 1e-9) / texels_per_metre)

    row_width = max(sizes[:, 0].max(), np.sqrt(((sizes + gutter).prod(axis=1)).sum()))
    origins = np.zeros_like(sizes)
    x = y = snap(gutter)
    shelf = width = 0.0
    for i in np.argsort(-sizes[:, 1], kind="stable"):
        w, h = sizes[i]
        if x > snap(gutter) and x + w > gutter + row_width:
            x, y, shelf = snap(gutter), snap(y + shelf + gutter), 0.0
        origins[i] = x, y
        x = snap(x + w + gutter)
        shelf, width = max(shelf, h), max(width, x)
    return origins, snap(max(width, snap(y + shelf + gutter)))


def assemble(patches: Sequence[Patch | None], texels_per_metre: float | None) -> Mesh:
    """Join logical faces into one Mesh, dropping collapsed triangles, and lay out their atlas."""
    kept = [p for p in patches if p is not None]
    verts, norms, charts, faces, ids = [], [], [], [], []
    offset = 0
    for fid, p in enumerate(kept, start=1):
        t = p.triangles
        # A collapsed ring (a cone's apex, a sphere's poles) leaves triangles with two corners on
        # one point: drop them, then the vertices nothing uses any more.
        c = p.points[t]
        flat = np.zeros(len(t), bool)
        for i, j in ((0, 1), (1, 2), (2, 0)):
            flat |= np.all(c[:, i] == c[:, j], axis=1)
        used, inverse = np.unique(t[~flat].ravel(), return_inverse=True)
        verts.append(p.points[used])
        norms.append(p.normals[used])
        charts.append(p.chart[used])
        faces.append(inverse.reshape(-1, 3) + offset)
        ids.append(np.full(len(faces[-1]), fid))
        offset += len(used)
    sizes = np.array([p.size for p in kept])
    origins, side = _pack(sizes, texels_per_metre)
    counts = [len(v) for v in verts]
    uv = (np.concatenate(charts) + np.repeat(origins, counts, axis=0)) / side
    return Mesh(
        vertices=np.concatenate(verts),
        faces=np.concatenate(faces).astype(np.int32),
        face_ids=np.concatenate(ids).astype(np.int32),
        face_names=[p.name for p in kept],
        normals=np.concatenate(norms),
        uv=uv,
        chart_size_m=sizes,
        chart_uv=np.hstack([origins, origins + sizes]) / side,
        atlas_size_m=float(side),
    )


#: Meshes made, the most recently asked for kept, by their maker's key (a primitive's: primitive,
#: segments, density): a house's screens ask again for the meshes of its hundreds of unchanged
#: primitives after every edit. A kept mesh's arrays are read-only, since every caller shares it.
MESH_CACHE_SIZE = 2048
_MESHES: OrderedDict[Hashable, Mesh] = OrderedDict()
_MESHES_LOCK = threading.Lock()


def kept_mesh(key: Hashable, make: Callable[[], Mesh]) -> Mesh:
    """The mesh kept under ``key``, else ``make()``'s, its arrays made read-only and kept."""
    with _MESHES_LOCK:
        kept = _MESHES.get(key)
        if kept is not None:
            _MESHES.move_to_end(key)
            return kept
    mesh = make()
    for f in dataclasses.fields(mesh):
        value = getattr(mesh, f.name)
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
    with _MESHES_LOCK:
        _MESHES[key] = mesh
        while len(_MESHES) > MESH_CACHE_SIZE:
            _MESHES.popitem(last=False)
    return mesh
