"""The scene as one world-space triangle mesh, and its texture atlas layout (pure numpy).

Every logical face of every primitive node (``Mesh.face_ids``) becomes one global face with a
1-based id, in model order; id 0 is "nothing" in GPU buffers. Each face gets a chart of whole
texels on one atlas page (a face no photo can see, a token chart of :data:`TOKEN_TEXELS` a side:
:mod:`vebuild.texture.visibility`); pages are at most ``page_size`` texels on a side (the GL maximum texture
size or less), so a scene whose texels do not fit one texture is split over several.

Used by texture extraction, and by anything that later draws the textured scene: given the same
model and the face records of an extraction, :func:`scene_mesh` rebuilds the same atlas coordinates.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import VebuildError
from vebuild.model.mesh import Mesh
from vebuild.model.scene import Model

Array = NDArray[np.float64]

#: Texels between charts and around a page's border; each chart bleeds into half of it.
GUTTER = 4
#: The side, in texels, of the token chart of a face no photo can see (its texels are all filled
#: from its node's seen faces, and marked unseen): enough for each texel of any chart's shape to
#: have on-face neighbours, so that the coverage map marks the whole face.
TOKEN_TEXELS = 4
#: Facets around curved surfaces.
SEGMENTS = 32
#: Memory the extraction takes per atlas texel: its per-page sums on the GPU (two RGBA float32
#: targets, one RGBA and one RG half-float target: 44 bytes; vebuild.texture.gpu) and the best
#: view's weight (4 bytes).
BYTES_PER_TEXEL = 48
#: The most atlas texels (gutters included) one extraction lays out: 2 GiB of the sums above, 44.7 M
#: texels, about 2.7 pages of 4096² (some 1,000 m² of faces at the default 200 texels per metre).
#: The sums live on the GPU (main memory on llvmpipe) all at once, and each page is read back for
#: the merge; a layout of 3.2 GB ended in "framebuffer is not complete" on llvmpipe instead of a
#: message.
MAX_ATLAS_TEXELS = (2 * 2**30) // BYTES_PER_TEXEL


@dataclass(frozen=True)
class Face:
    """One logical face: ``node``'s face ``name``, on ``page`` at texel rectangle ``rect``."""

    id: int  # 1-based global id
    node: str
    name: str
    size_m: tuple[float, float]  # chart width, height in metres
    page: int
    rect: tuple[int, int, int, int]  # x0, y0, width, height in texels

    @property
    def texels_per_metre(self) -> tuple[float, float]:
        return (self.rect[2] / self.size_m[0], self.rect[3] / self.size_m[1])


@dataclass(frozen=True)
class SceneMesh:
    """The model's primitives in world coordinates, one mesh, with atlas coordinates.

    vertices, normals : (n, 3) world positions (metres) and unit normals.
    triangles : (m, 3) int32 into vertices, counter-clockwise seen from outside.
    face_of_vertex : (n,) int32 global face id (vertices are not shared between faces).
    atlas : (n, 2) float64 position in texels on its face's page.
    faces : the faces, ``faces[id - 1]`` has that id.
    pages : (width, height) of each page in texels.
    """

    vertices: Array
    normals: Array
    triangles: NDArray[np.int32]
    face_of_vertex: NDArray[np.int32]
    atlas: Array
    faces: list[Face]
    pages: list[tuple[int, int]]

    @property
    def triangle_faces(self) -> NDArray[np.int32]:
        return self.face_of_vertex[self.triangles[:, 0]]

    def triangle_soup(self) -> dict[str, Array]:
        """Per-corner arrays for drawing in atlas space, three rows per triangle.

        position, normal (3), atlas (2), face (1), page (1), and the triangle's world steps of one
        atlas texel e_u, e_v (3 each). Triangles with no area in the atlas are left out.
        """
        t = self.triangles
        P, A = self.vertices[t], self.atlas[t]  # (m, 3, 3), (m, 3, 2)
        dP = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2)  # (m, 3, 2)
        dA = np.stack([A[:, 1] - A[:, 0], A[:, 2] - A[:, 0]], axis=2)  # (m, 2, 2)
        det = dA[:, 0, 0] * dA[:, 1, 1] - dA[:, 0, 1] * dA[:, 1, 0]
        ok = np.abs(det) > 1e-9
        inv = np.zeros_like(dA)
        inv[ok] = np.linalg.inv(dA[ok])
        E = dP @ inv  # (m, 3, 2): columns dP/dx, dP/dy
        faces = self.triangle_faces[ok]
        pages = np.array([f.page for f in self.faces], dtype=np.int32)[faces - 1]
        rep = lambda a: np.repeat(a, 3, axis=0)  # noqa: E731
        return {
            "position": P[ok].reshape(-1, 3),
            "normal": self.normals[t[ok]].reshape(-1, 3),
            "atlas": A[ok].reshape(-1, 2),
            "face": rep(faces),
            "page": rep(pages),
            "e_u": rep(E[ok, :, 0]),
            "e_v": rep(E[ok, :, 1]),
        }

    def boundary_edges(self) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Edges of the faces, welded by position: (k, 2) vertex pairs on a face's border (one
        triangle of that face uses them), and (e, 4) interior edges as (a, b, triangle 1,
        triangle 2) for finding silhouettes of curved faces."""
        key = np.round(self.vertices, 9)
        _, weld = np.unique(np.column_stack([key, self.face_of_vertex]), axis=0, return_inverse=True)
        weld = weld.ravel()
        t = self.triangles
        e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
        tri = np.tile(np.arange(len(t)), 3)
        w = np.sort(weld[e], axis=1)
        _, inv, counts = np.unique(w, axis=0, return_inverse=True, return_counts=True)
        inv = inv.ravel()
        border = counts[inv] == 1
        order = np.argsort(inv, kind="stable")
        pairs = order[counts[inv[order]] == 2].reshape(-1, 2)  # two uses of one welded edge
        interior = np.column_stack([e[pairs[:, 0]], tri[pairs[:, 0]], tri[pairs[:, 1]]])
        return e[border], interior


def _texels(length_m: float, texels_per_metre: float, cap: int) -> int:
    """Texels along a chart side of ``length_m`` (finite, ≥ 0), at most ``cap``, overflow-safe: the
    product is compared in floating point before it is turned into an integer."""
    t = length_m * texels_per_metre - 1e-9
    return cap if not t < cap else max(1, math.ceil(t))


def plan_faces(model: Model, texels_per_metre: float, max_face_texels: int, page_size: int,
               token: Collection[tuple[str, str]] = ()) -> list[tuple[str, str, tuple[float, float], tuple[int, int]]]:
    """(node, face name, chart size in metres, chart size in texels) of every face, model order;
    the faces (node, face name) in ``token`` get a token chart (:data:`TOKEN_TEXELS` a side, or
    less under a smaller cap).

    A face whose size is not a finite number of metres (a primitive sized beyond floating point)
    is a :class:`LayoutError` naming it."""
    if not (math.isfinite(texels_per_metre) and texels_per_metre > 0):
        raise LayoutError(f"--density: expected a positive number of texels per metre, got {texels_per_metre!r}")
    cap = max(1, min(int(max_face_texels), int(page_size) - 2 * GUTTER))
    small = min(TOKEN_TEXELS, cap)
    out = []
    for node in model.nodes:
        if node.primitive is None:
            continue
        mesh = node.primitive.mesh(None, SEGMENTS)
        for name, (w, h) in zip(mesh.face_names, mesh.chart_size_m, strict=True):
            w, h = float(w), float(h)
            if not (math.isfinite(w) and math.isfinite(h) and w >= 0 and h >= 0):
                raise LayoutError(f"node '{node.name}' face '{name}': its chart is {w:g} m × {h:g} m, not a finite "
                                  "size; give the primitive finite dimensions in metres")
            if (node.name, name) in token:
                out.append((node.name, name, (w, h), (small, small)))
                continue
            out.append((node.name, name, (w, h), (_texels(w, texels_per_metre, cap),
                                                  _texels(h, texels_per_metre, cap))))
    return out


class LayoutError(VebuildError):
    """The faces' textures cannot be laid out: a face of no finite size, or an atlas too large."""


def atlas_bytes(texels: int) -> int:
    """Memory the extraction takes for ``texels`` atlas texels (:data:`BYTES_PER_TEXEL` each)."""
    return int(texels) * BYTES_PER_TEXEL


def _packed_texels(sizes_m: Sequence[tuple[float, float]], texels_per_metre: float, cap: int, page_size: int,
                   fixed: Sequence[tuple[int, int]] = ()) -> int:
    """Texels of the pages that charts of these sizes in metres pack into at a density (with the
    charts ``fixed`` in texels, whatever the density: the token charts)."""
    _, pages = pack([(_texels(w, texels_per_metre, cap), _texels(h, texels_per_metre, cap)) for w, h in sizes_m]
                    + list(fixed), page_size)
    return sum(w * h for w, h in pages)  # Python ints: no overflow


def check_atlas(plan: Sequence[tuple[str, str, tuple[float, float], tuple[int, int]]], texels_per_metre: float,
                max_face_texels: int, page_size: int, max_texels: int,
                token: Collection[tuple[str, str]] = ()) -> tuple[list[tuple[int, int, int]], list[tuple[int, int]]]:
    """Pack the charts of ``plan`` (:func:`pack`) and refuse pages of more than ``max_texels``
    texels in all (see :data:`MAX_ATLAS_TEXELS`) before anything is allocated: the message names
    the largest faces, the texels and pages the layout would need, the limit, and the density that
    would fit."""
    place, pages = pack([n for *_, n in plan], page_size)
    need = sum(w * h for w, h in pages)
    if need <= max_texels:
        return place, pages
    cap = max(1, min(int(max_face_texels), int(page_size) - 2 * GUTTER))
    sizes_m = [size for node, face, size, _ in plan if (node, face) not in token]
    fixed = [n for node, face, _, n in plan if (node, face) in token]
    biggest = sorted(plan, key=lambda p: -p[3][0] * p[3][1])[:3]
    faces = "; ".join(f"node '{n}' face '{f}' {w}×{h} texels ({a:g} m × {b:g} m)" for n, f, (a, b), (w, h) in biggest)
    what = (f"the texture atlas would need {need:,} texels on {len(pages)} page(s) of at most {page_size}² "
            f"({atlas_bytes(need) / 2**30:.1f} GiB for the extraction's sums at {BYTES_PER_TEXEL} bytes a texel) at "
            f"{texels_per_metre:g} texels per metre: more than the limit of {max_texels:,} texels "
            f"({atlas_bytes(max_texels) / 2**30:.0f} GiB); the largest faces: {faces}")
    if _packed_texels(sizes_m, 1e-300, cap, page_size, fixed) > max_texels:
        raise LayoutError(f"{what}. The model has {len(plan)} faces: too many to texture even at one texel each; "
                          "texture fewer objects (or use --mode average)")
    lo, hi = 0.0, float(texels_per_metre)  # the densest that fits, by bisection (the pages grow with density)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _packed_texels(sizes_m, mid, cap, page_size, fixed) <= max_texels else (lo, mid)
    digits = 2 - math.floor(math.log10(lo)) if lo > 0 else 3
    fit = math.floor(lo * 10.0 ** digits) / 10.0 ** digits  # three figures, rounded down
    while fit > 0 and _packed_texels(sizes_m, fit, cap, page_size, fixed) > max_texels:
        fit = math.floor(fit * 0.99 * 10.0 ** digits) / 10.0 ** digits
    raise LayoutError(f"{what}. Lower --density (texels per metre) to {fit:g} or less, or lower --max-face-texels")


def pack(sizes: Sequence[tuple[int, int]], page_size: int) -> tuple[list[tuple[int, int, int]], list[tuple[int, int]]]:
    """Shelf-pack charts (w, h) in texels into pages of at most ``page_size``; tallest first.

    Returns each chart's (page, x0, y0) and each page's (width, height). Rows are about
    √(total area) wide so that a scene that fits one page packs into a near-square one.
    """
    sizes = [(int(w), int(h)) for w, h in sizes]
    if any(w + 2 * GUTTER > page_size or h + 2 * GUTTER > page_size for w, h in sizes):
        raise ValueError("a chart is larger than a page")
    area = sum((w + GUTTER) * (h + GUTTER) for w, h in sizes)
    widest = max((w for w, _ in sizes), default=1)
    row_width = min(page_size - GUTTER, max(widest + GUTTER, math.ceil(1.1 * math.sqrt(area))))
    place: list[tuple[int, int, int]] = [(0, 0, 0)] * len(sizes)
    pages: list[list[int]] = [[GUTTER, GUTTER]]  # used width, height per page
    x = y = GUTTER
    shelf = 0
    for i in sorted(range(len(sizes)), key=lambda k: (-sizes[k][1], k)):
        w, h = sizes[i]
        if x > GUTTER and x + w + GUTTER > row_width + GUTTER:
            x, y, shelf = GUTTER, y + shelf + GUTTER, 0
        if y + h + GUTTER > page_size:
            pages.append([GUTTER, GUTTER])
            x, y, shelf = GUTTER, GUTTER, 0
        place[i] = (len(pages) - 1, x, y)
        x += w + GUTTER
        shelf = max(shelf, h)
        pages[-1][0] = max(pages[-1][0], x)
        pages[-1][1] = max(pages[-1][1], y + h + GUTTER)
    return place, [(int(w), int(h)) for w, h in pages]


def layout(model: Model, texels_per_metre: float, max_face_texels: int, page_size: int,
           max_texels: int | None = None, token: Collection[tuple[str, str]] = ()) -> list[Face]:
    """Faces with charts packed into pages, once the pages' texels are known to be within
    ``max_texels`` (default :data:`MAX_ATLAS_TEXELS`; :func:`check_atlas`); the faces (node, face
    name) in ``token`` with token charts (:func:`plan_faces`)."""
    plan = plan_faces(model, texels_per_metre, max_face_texels, page_size, token)
    place, _ = check_atlas(plan, texels_per_metre, max_face_texels, page_size,
                           MAX_ATLAS_TEXELS if max_texels is None else int(max_texels), token)
    return [Face(i + 1, node, name, size, page, (x, y, n[0], n[1]))
            for i, ((node, name, size, n), (page, x, y)) in enumerate(zip(plan, place, strict=True))]


def page_sizes(faces: Sequence[Face]) -> list[tuple[int, int]]:
    """Each page's size: the extent of its charts plus the gutter."""
    out: dict[int, list[int]] = {}
    for f in faces:
        x0, y0, w, h = f.rect
        p = out.setdefault(f.page, [GUTTER, GUTTER])
        p[0], p[1] = max(p[0], x0 + w + GUTTER), max(p[1], y0 + h + GUTTER)
    return [tuple(out[k]) for k in sorted(out)]  # type: ignore[misc]


def node_atlas(node: str, mesh: Mesh, faces: Mapping[tuple[str, str], Face]) -> tuple[NDArray[np.int32], Array]:
    """Each vertex's global face id and atlas position of primitive node ``node``'s local ``mesh``.

    ``faces`` maps (node name, face name) to the face's record (as :func:`layout` gave). The atlas
    position is in texels on the face's page (row 0 is the page's top row): the mesh's chart
    coordinates scaled to the face's ``rect``. Raises ValueError if a face has no record.
    """
    vid = np.zeros(len(mesh.vertices), dtype=np.int32)
    vid[mesh.faces.ravel()] = np.repeat(mesh.face_ids, 3)
    gid = np.empty(len(mesh.vertices), dtype=np.int32)
    uv_tex = np.empty((len(mesh.vertices), 2))
    for k, name in enumerate(mesh.face_names, start=1):
        face = faces.get((node, name))
        if face is None:
            raise ValueError(f"the texture layout has no face {node}.{name}")
        sel = vid == k
        u0, v0, u1, v1 = (float(c) for c in mesh.chart_uv[k - 1])
        if not (math.isfinite(u1 - u0) and math.isfinite(v1 - v0) and u1 != u0 and v1 != v0):
            raise ValueError(f"face {node}.{name} has an empty or non-finite chart ({u0:g}–{u1:g}, {v0:g}–{v1:g}); "
                             "its primitive's dimensions are degenerate")
        x0, y0, w, h = face.rect
        uv = mesh.uv[sel]
        uv_tex[sel, 0] = x0 + (uv[:, 0] - u0) / (u1 - u0) * w
        uv_tex[sel, 1] = y0 + (uv[:, 1] - v0) / (v1 - v0) * h
        gid[sel] = face.id
    return gid, uv_tex


def scene_mesh(model: Model, faces: Sequence[Face]) -> SceneMesh:
    """The world mesh of ``model`` with atlas coordinates from ``faces`` (as :func:`layout` gave)."""
    transforms = model.world_transforms()
    by_key = {(f.node, f.name): f for f in faces}
    verts, norms, tris, fov, atlas = [], [], [], [], []
    offset = 0
    for node in model.nodes:
        if node.primitive is None:
            continue
        mesh = node.primitive.mesh(None, SEGMENTS)
        T = transforms[node.name]
        gid, uv_tex = node_atlas(node.name, mesh, by_key)
        verts.append(mesh.vertices @ T[:3, :3].T + T[:3, 3])
        norms.append(mesh.normals @ T[:3, :3].T)
        tris.append(mesh.faces + offset)
        fov.append(gid)
        atlas.append(uv_tex)
        offset += len(mesh.vertices)
    faces = sorted(faces, key=lambda f: f.id)
    return SceneMesh(
        vertices=np.concatenate(verts) if verts else np.zeros((0, 3)),
        normals=np.concatenate(norms) if norms else np.zeros((0, 3)),
        triangles=np.concatenate(tris).astype(np.int32) if tris else np.zeros((0, 3), np.int32),
        face_of_vertex=np.concatenate(fov).astype(np.int32) if fov else np.zeros(0, np.int32),
        atlas=np.concatenate(atlas) if atlas else np.zeros((0, 2)),
        faces=list(faces),
        pages=page_sizes(faces),
    )
