"""The CPU reference of texture extraction: passes 1–2 and the per-texel sums, in numpy.

The same definitions as the GPU path (:mod:`vebuild.texture.gpu`, ``shaders/id.*``,
``shaders/pyramid.frag``, ``shaders/texel.frag``), stated once in :mod:`vebuild.texture`, computed
here in float64 without OpenGL. It is the yardstick the GPU is tested against and the baseline the
texture benchmark compares it with, so it is written to be right first and reasonably fast second:
every pass is vectorised over pixels or texels and works in chunks of at most :data:`CHUNK`
elements, and :func:`accumulate` holds one photo (its pyramid and ID buffer) at a time.

Where the GPU path is an approximation of a definition, this module says which way it goes:

* Rasterisation (ID buffer and atlas) samples at pixel centres and counts a centre lying exactly
  on a triangle's edge as inside (GL's tie rule picks one of two triangles sharing the edge; the
  two agree on the face there, so the choice only matters at rounding level).
* Depth is compared exactly in float64 (GL compares a 24-bit window depth); among equal depths the
  triangle drawn first wins, as with GL's ``<`` depth test.
* Erosion is morphological (see :func:`~vebuild.texture.raster.rasterise_ids`, pass 1, in its own
  module) where the GPU draws every visible face
  border and silhouette as a band ``erode_px`` wide either side, depth-tested against the faces.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import Lens, distortion_derivatives
from vebuild.texture import BEST_WEIGHT_SCALE, DEPTH_TOLERANCE, MAX_LEVELS, pre_pass_erosion
from vebuild.texture.layout import SceneMesh
from vebuild.texture.lens import pinhole_cover
from vebuild.texture.merge import srgb8_to_linear
from vebuild.texture.raster import CHUNK, EDGE_EPS, rasterise_ids, scan_triangle  # noqa: F401  (re-exported: the reference's pass 1)

if TYPE_CHECKING:  # gpu.py imports moderngl; the reference must run without it
    from vebuild.camera import ImageCamera
    from vebuild.texture.options import Options

Array = NDArray[np.float64]

# -- colour --------------------------------------------------------------------------------------


_SRGB_LUT = srgb8_to_linear(np.arange(256, dtype=np.uint8))


def pyramid(pixels_uint8: NDArray[np.uint8]) -> list[Array]:
    """The photo's box pyramid in linear light (float64, (h, w, channels) per level).

    Level 0 is the photo decoded from 8-bit sRGB with the exact formula; level k + 1 is
    ``ceil(W_k / 2) × ceil(H_k / 2)`` and its texel (i, j) is the mean of the level-k texels
    {2i, min(2i + 1, W_k − 1)} × {2j, min(2j + 1, H_k − 1)}. Up to :data:`MAX_LEVELS` levels, or
    until a level is 1 × 1.
    """
    px = np.asarray(pixels_uint8)
    if px.dtype != np.uint8:
        raise ValueError(f"expected uint8 pixels, got {px.dtype}")
    if px.ndim == 2:
        px = px[..., None]
    levels = [_SRGB_LUT[px]]
    while len(levels) < MAX_LEVELS and max(levels[-1].shape[:2]) > 1:
        a = levels[-1]
        h, w = a.shape[:2]
        if w % 2:
            a = np.concatenate([a, a[:, -1:]], axis=1)
        if h % 2:
            a = np.concatenate([a, a[-1:]], axis=0)
        levels.append(0.25 * ((a[0::2, 0::2] + a[0::2, 1::2]) + (a[1::2, 0::2] + a[1::2, 1::2])))
    return levels


def _bilinear(level: Array, q: Array) -> Array:
    """Bilinear sample of one level at q (n, 2) in its texel units: texel centres at half-integers,
    q clamped to [0.5, size − 0.5] per axis (which is GL's clamp-to-edge)."""
    h, w = level.shape[:2]
    flat = level.reshape(h * w, -1)
    x = np.clip(q[:, 0], 0.5, w - 0.5) - 0.5
    y = np.clip(q[:, 1], 0.5, h - 0.5) - 0.5
    i0 = np.floor(x).astype(np.intp)
    j0 = np.floor(y).astype(np.intp)
    fx = (x - i0)[:, None]
    fy = (y - j0)[:, None]
    i1 = np.minimum(i0 + 1, w - 1)
    j1 = np.minimum(j0 + 1, h - 1)
    top = flat[j0 * w + i0] * (1.0 - fx) + flat[j0 * w + i1] * fx
    bottom = flat[j1 * w + i0] * (1.0 - fx) + flat[j1 * w + i1] * fx
    return top * (1.0 - fy) + bottom * fy


def trilinear(levels: Sequence[Array], p: Array, lod: Array) -> Array:
    """Trilinear samples of a :func:`pyramid` at level-0 pixel positions p (..., 2) and levels of
    detail lod (...): lod is clamped to [0, L − 1]; level k is sampled bilinearly at p / 2^k (see
    :func:`_bilinear`); the result mixes levels floor(lod) and floor(lod) + 1 by lod's fraction."""
    p = np.asarray(p, float)
    lod = np.broadcast_to(np.asarray(lod, float), p.shape[:-1])
    shape = p.shape[:-1]
    p, lod = p.reshape(-1, 2), lod.reshape(-1)
    channels = levels[0].shape[2] if levels[0].ndim == 3 else 1
    out = np.zeros((len(p), channels))
    lod = np.clip(lod, 0.0, float(len(levels) - 1))
    k = np.floor(lod).astype(np.intp)
    t = lod - k
    for m, level in enumerate(levels):
        lo = np.flatnonzero(k == m)
        hi = np.flatnonzero((k + 1 == m) & (t > 0.0))
        sel = np.concatenate([lo, hi])
        if not len(sel):
            continue
        s = _bilinear(level, p[sel] / 2.0**m)
        wt = np.concatenate([1.0 - t[lo], t[hi]])[:, None]
        out[sel] += wt * s  # lo and hi are disjoint (k = m and k = m − 1)
    return out.reshape(*shape, channels)


# -- the atlas -------------------------------------------------------------------------------------


@dataclass
class PageTexels:
    """The texels of one page that lie on a face, as flat arrays (n, ...) in row-major order of
    the page (``index`` = j · width + i)."""

    shape: tuple[int, int]  # (h, w)
    index: NDArray[np.intp]
    position: Array
    normal: Array  # unit
    face: NDArray[np.int32]
    e_u: Array
    e_v: Array

    def __len__(self) -> int:
        return len(self.index)

    def dense(self) -> dict[str, NDArray]:
        h, w = self.shape
        out: dict[str, NDArray] = {}
        for name in ("position", "normal", "e_u", "e_v"):
            a = np.zeros((h * w, 3))
            a[self.index] = getattr(self, name)
            out[name] = a.reshape(h, w, 3)
        f = np.zeros(h * w, np.int32)
        f[self.index] = self.face
        out["face"] = f.reshape(h, w)
        return out

    @classmethod
    def from_dense(cls, g: dict[str, NDArray]) -> PageTexels:
        face = np.asarray(g["face"])
        h, w = face.shape
        index = np.flatnonzero(face.ravel() > 0)
        take = lambda name: np.asarray(g[name], float).reshape(h * w, 3)[index]  # noqa: E731
        n = take("normal")
        return cls((h, w), index, take("position"), n / np.linalg.norm(n, axis=1, keepdims=True),
                   face.ravel()[index].astype(np.int32), take("e_u"), take("e_v"))


def page_texels(mesh: SceneMesh, page: int, soup: dict[str, Array] | None = None) -> PageTexels:
    """The atlas triangles of ``page`` rasterised at texel centres (compact form of
    :func:`texel_geometry`)."""
    soup = mesh.triangle_soup() if soup is None else soup
    w, h = mesh.pages[page]
    tri_page = soup["page"][0::3]
    tris = np.flatnonzero(tri_page == page)
    A = soup["atlas"].reshape(-1, 3, 2)
    owner = np.full(h * w, -1, np.intp)
    for t in tris:
        for i, j, _ in scan_triangle(A[t], w, h):
            idx = j * w + i
            free = owner[idx] < 0  # a centre on a shared edge keeps its first triangle
            owner[idx[free]] = t
    index = np.flatnonzero(owner >= 0)
    tri = owner[index]
    # Position and normal are affine in atlas space on each triangle: values = [x, y, 1] @ G[t].
    corners = np.concatenate([A, np.ones((len(A), 3, 1))], axis=2)  # (m, 3, 3)
    values = np.concatenate([soup["position"].reshape(-1, 3, 3), soup["normal"].reshape(-1, 3, 3)], axis=2)
    G = np.zeros((len(A), 3, 6))
    G[tris] = np.linalg.solve(corners[tris], values[tris])
    pos = np.empty((len(index), 3))
    nor = np.empty((len(index), 3))
    for lo, hi in _chunks(len(index)):
        ts = tri[lo:hi]
        x = (index[lo:hi] % w + 0.5)[:, None]
        y = (index[lo:hi] // w + 0.5)[:, None]
        v = x * G[ts, 0] + y * G[ts, 1] + G[ts, 2]
        pos[lo:hi] = v[:, :3]
        nor[lo:hi] = v[:, 3:] / np.sqrt(np.einsum("ij,ij->i", v[:, 3:], v[:, 3:]))[:, None]
    return PageTexels((h, w), index, pos, nor, soup["face"][3 * tri].astype(np.int32),
                      soup["e_u"][3 * tri].astype(float), soup["e_v"][3 * tri].astype(float))


def texel_geometry(mesh: SceneMesh, page: int) -> dict[str, NDArray]:
    """Each texel of ``page``: 'position' (h, w, 3) world point, 'normal' (h, w, 3) unit normal,
    'face' (h, w) int32 (0: on no face), 'e_u', 'e_v' (h, w, 3) world steps of one texel along
    atlas x and y. The page's triangles (``mesh.triangle_soup()``) are rasterised in atlas space at
    texel centres (i + ½, j + ½) and their corners' values interpolated linearly (normals then
    normalised); texels on no face are zero."""
    return page_texels(mesh, page).dense()


# -- pass 2 ----------------------------------------------------------------------------------------


@dataclass
class _Projected:
    """Where the seen texels of a chunk project: their positions in the chunk, p, a, b, w."""

    sel: NDArray[np.intp]
    p: Array
    a: Array
    b: Array
    weight: Array


def _rows(X: Array, M: Array) -> Array:
    """X @ M.T for many rows X (n, k) and a small matrix M (m, k) (einsum: BLAS is slow at this
    shape)."""
    return np.einsum("nk,mk->nm", X, M)


def _project(tx: PageTexels, lo: int, hi: int, cam: ImageCamera, ids: NDArray[np.int32], depth: Array,
             weight_scale: float = 1.0) -> _Projected:
    """texel.frag up to the weight, for texels lo:hi of ``tx``: the seen test and w.

    ``ids``/``depth`` are the ID buffer of ``cam``'s pinhole cover (:func:`rasterise_ids`): a
    texel is tested there at its pinhole pixel p − origin; then, for a photo with lens distortion,
    p and its footprint are distorted (the division model's closed form and its Jacobian), and the
    distorted p must lie in the photo.
    """
    K = np.asarray(cam.K, float)
    R = np.asarray(cam.R, float)
    C = np.asarray(cam.C, float)
    cover, origin = pinhole_cover(cam)
    width, height = int(cover.width), int(cover.height)
    o = np.array(origin, float)
    P, N, F = tx.position[lo:hi], tx.normal[lo:hi], tx.face[lo:hi]
    to_cam = C - P
    x = _rows(-to_cam, R)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = np.einsum("ij,ij->i", N, to_cam) / np.sqrt(np.einsum("ij,ij->i", to_cam, to_cam))
        ok = (x[:, 2] > 0) & (cos > 0)
        hh = _rows(x, K)
        p = hh[:, :2] / hh[:, 2:3]
        q = p - o
    ok &= (q[:, 0] >= 0) & (q[:, 1] >= 0) & (q[:, 0] < width) & (q[:, 1] < height)
    sel = np.flatnonzero(ok)
    x, p, q, F, cos = x[sel], p[sel], q[sel], F[sel], cos[sel]
    pix = np.floor(q[:, 1]).astype(np.intp) * width + np.floor(q[:, 0]).astype(np.intp)
    ids_flat, depth_flat = ids.reshape(-1), depth.reshape(-1)
    ok = (ids_flat[pix] == F) & (x[:, 2] <= (1.0 + DEPTH_TOLERANCE) * depth_flat[pix])
    sel, x, p, q, F, cos = sel[ok], x[ok], p[ok], q[ok], F[ok], cos[ok]
    # The Jacobian of the projection at the texel applied to its steps: a = J e_u, b = J e_v.
    du = _rows(tx.e_u[lo:hi][sel], R)
    dv = _rows(tx.e_v[lo:hi][sel], R)
    z = x[:, 2:3]
    a = (_rows(du, K[:2]) - p * du[:, 2:3]) / z
    b = (_rows(dv, K[:2]) - p * dv[:, 2:3]) / z
    ok = np.ones(len(sel), bool)
    for sa in (1.0, -1.0):
        for sb in (1.0, -1.0):
            c = q + sa * a + sb * b
            inside = (c[:, 0] >= 0) & (c[:, 1] >= 0) & (c[:, 0] < width) & (c[:, 1] < height)
            c = np.where(inside[:, None], c, 0.0)
            ok &= inside & (ids_flat[np.floor(c[:, 1]).astype(np.intp) * width
                                     + np.floor(c[:, 0]).astype(np.intp)] == F)
    if not cam.lens.is_pinhole:
        p, a, b, inside = _distort(K, cam.lens, p, a, b, int(cam.width), int(cam.height))
        ok &= inside
    w = np.sqrt(np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])) * cos * weight_scale
    return _Projected(sel[ok], p[ok], a[ok], b[ok], w[ok])


def _distort(K: Array, lens: Lens, p: Array, a: Array, b: Array, width: int,
             height: int) -> tuple[Array, Array, Array, NDArray[np.bool_]]:
    """Pinhole pixels p (n, 2) and footprints a, b → where the ``lens`` puts them, and whether
    the footprint's corners p ± a ± b lie in the width × height photo (and in the lens's field).

    x_d = s x_u with s = 2 / (1 + √(1 − 4 k1 |x_u|²)) for one term
    (:func:`vebuild.camera.distort_normalised`); its Jacobian s I + (2 k1 s² / √(1 − 4 k1 |x_u|²))
    x_u x_uᵀ maps the footprint (in pixels too, as x is divided by f on both sides). With two terms,
    s and g = 2 ∂s/∂|x_u|² from :func:`vebuild.camera.distortion_derivatives`, the field ending
    where the map stops opening out (shaders/texel.frag does the same).
    """
    f, c = K[0, 0], K[:2, 2]
    xu = (p - c) / f
    k1 = lens.k1
    r2 = np.einsum("ij,ij->i", xu, xu)
    if lens.k2 == 0.0:
        disc = 1.0 - 4.0 * k1 * r2
        field = disc > 0.0  # beyond it (a pincushion lens only) no photo shows anything
        root = np.sqrt(np.where(field, disc, 1.0))
        s = 2.0 / (1.0 + root)
        g = 2.0 * k1 * s * s / root
    else:
        s, ds_dr2, _, _ = distortion_derivatives(r2, lens)
        field = 1.0 - 2.0 * k1 * s * r2 - 4.0 * lens.k2 * s**3 * r2**2 > 0.0
        g = 2.0 * ds_dr2
    pd = c + f * s[:, None] * xu
    ad = s[:, None] * a + (g * np.einsum("ij,ij->i", xu, a))[:, None] * xu
    bd = s[:, None] * b + (g * np.einsum("ij,ij->i", xu, b))[:, None] * xu
    inside = field.copy()
    for sa in (1.0, -1.0):  # the footprint in the photo, as the ID buffer's frame is the photo's for a pinhole
        for sb in (1.0, -1.0):
            c = pd + sa * ad + sb * bd
            inside &= (c[:, 0] >= 0) & (c[:, 1] >= 0) & (c[:, 0] < width) & (c[:, 1] < height)
    return pd, ad, bd, inside


def _lod(pr: _Projected) -> Array:
    size = np.maximum(np.linalg.norm(pr.a, axis=1), np.linalg.norm(pr.b, axis=1))
    return np.log2(np.maximum(size, 1e-6))


def _chunks(n: int) -> Iterator[tuple[int, int]]:
    for lo in range(0, n, CHUNK):
        yield lo, min(n, lo + CHUNK)


def texel_view(mesh: SceneMesh, cam: ImageCamera, levels: Sequence[Array], ids: NDArray[np.int32], depth: Array,
               page: int, detail_levels: float = 2.0,
               geometry: dict[str, NDArray] | PageTexels | None = None) -> dict[str, NDArray]:
    """One photo's texels on one page (texel.frag, MODE 1, atlas_scale 1, weight_scale 1).

    Returns 'colour' (h, w, 3) c, 'weight' (h, w) w, 'low' (h, w, 3) l and 'seen' (h, w) bool;
    zeros where not seen. ``levels`` is the photo's :func:`pyramid`, ``ids``/``depth`` its
    :func:`rasterise_ids`; ``geometry`` (:func:`texel_geometry` or :func:`page_texels` of this
    page) saves rasterising the page again.
    """
    if geometry is None:
        tx = page_texels(mesh, page)
    elif isinstance(geometry, PageTexels):
        tx = geometry
    else:
        tx = PageTexels.from_dense(geometry)
    h, w = tx.shape
    colour = np.zeros((h * w, 3))
    low = np.zeros((h * w, 3))
    weight = np.zeros(h * w)
    seen = np.zeros(h * w, bool)
    for lo, hi in _chunks(len(tx)):
        pr = _project(tx, lo, hi, cam, ids, depth)
        if not len(pr.sel):
            continue
        idx = tx.index[lo + pr.sel]
        lod = _lod(pr)
        colour[idx] = trilinear(levels, pr.p, lod)[:, :3]
        low[idx] = trilinear(levels, pr.p, lod + detail_levels)[:, :3]
        weight[idx] = pr.weight
        seen[idx] = True
    return {"colour": colour.reshape(h, w, 3), "weight": weight.reshape(h, w), "low": low.reshape(h, w, 3),
            "seen": seen.reshape(h, w)}


def best_weights(mesh: SceneMesh, cameras: Iterable[ImageCamera], erode_px: float,
                 pages: Sequence[PageTexels] | None = None) -> list[Array]:
    """The pre-pass of :func:`accumulate` (texel.frag MODE 2, as ``Extractor.best_weights``):
    per page, each face texel's (compact order) best weight over ``cameras``, each seen through an
    ID buffer at half resolution (``cam.scaled(0.5)``, erosion ``gpu.pre_pass_erosion``) with weights
    doubled so that they are on the full-resolution scale."""
    pages = [page_texels(mesh, k) for k in range(len(mesh.pages))] if pages is None else pages
    best = [np.zeros(len(t)) for t in pages]
    for cam in cameras:
        small = cam.scaled(BEST_WEIGHT_SCALE)
        ids, depth = rasterise_ids(mesh, small, pre_pass_erosion(erode_px))
        for tx, b in zip(pages, best, strict=True):
            for lo, hi in _chunks(len(tx)):
                pr = _project(tx, lo, hi, small, ids, depth, weight_scale=1.0 / BEST_WEIGHT_SCALE)
                b[lo + pr.sel] = np.maximum(b[lo + pr.sel], pr.weight)
    return best


def accumulate(mesh: SceneMesh, cameras: Sequence[ImageCamera], photos: Iterable[NDArray[np.uint8]],
               options: Options, gains: dict[str, NDArray] | None = None) -> list[dict[str, NDArray]]:
    """Passes 1–2 for every photo, summed per texel: per page the four arrays of
    ``Extractor.sums`` (texel.frag MODE 0), float64:

    'low' (h, w, 4) = (Σ w l/g, Σ w) and 'detail' (h, w, 4) = (Σ w^s (c − l)/g, Σ w^s) over kept
    views, 'dropped' (h, w, 4) = (Σ v c/g, Σ v) over dropped views with v = w / the texel's best
    weight (as the GPU keeps them, in half floats), 'counts' (h, w, 2) = (kept, dropped) views;
    s = ``options.detail_sharpness`` with w clamped to [1e-4, 1e4] first, g the photo's gain
    (``gains[id]``, (3,); 1 when ``gains`` is None).

    With ``options.drop_ratio`` > 0 a view is kept when w ≥ drop_ratio × the texel's best weight
    from :func:`best_weights` (the GPU's half-resolution pre-pass). Photos are consumed one at a
    time (``photos`` may be a generator): one photo's pyramid and ID buffer are in memory at once.
    """
    cameras = list(cameras)
    soup = mesh.triangle_soup()
    pages = [page_texels(mesh, k, soup) for k in range(len(mesh.pages))]
    drop = float(options.drop_ratio)
    best = best_weights(mesh, cameras, float(options.erode_px), pages) if drop > 0 else None
    sums = [np.zeros((len(t), 14)) for t in pages]  # low 4, detail 4, dropped 4, counts 2
    s = float(options.detail_sharpness)
    for cam, pixels in zip(cameras, photos, strict=True):
        pixels = np.asarray(pixels)
        if pixels.shape[:2] != (cam.height, cam.width):
            raise ValueError(f"photo {cam.id}: pixels are {pixels.shape[1]}×{pixels.shape[0]}, "
                             f"the camera is for {cam.width}×{cam.height}")
        if gains is None:
            inv_gain = np.ones(3)
        elif cam.id in gains:
            inv_gain = 1.0 / np.asarray(gains[cam.id], float).reshape(3)
        else:
            raise ValueError(f"no gain for photo {cam.id}")
        levels = pyramid(pixels)
        del pixels
        ids, depth = rasterise_ids(mesh, cam, float(options.erode_px))
        for k, tx in enumerate(pages):
            acc = sums[k]
            for lo, hi in _chunks(len(tx)):
                pr = _project(tx, lo, hi, cam, ids, depth)
                if not len(pr.sel):
                    continue
                lod = _lod(pr)
                c = trilinear(levels, pr.p, lod)[:, :3]
                low = trilinear(levels, pr.p, lod + float(options.detail_levels))[:, :3]
                w = pr.weight
                rows = lo + pr.sel
                keep = np.ones(len(w), bool) if best is None else w >= drop * best[k][rows]
                wk, rk = w[keep], rows[keep]
                ws = np.clip(wk, 1e-4, 1e4) ** s
                acc[rk, 0:3] += wk[:, None] * low[keep] * inv_gain
                acc[rk, 3] += wk
                acc[rk, 4:7] += ws[:, None] * (c[keep] - low[keep]) * inv_gain
                acc[rk, 7] += ws
                acc[rk, 12] += 1.0
                rd = rows[~keep]
                vd = w[~keep] / best[k][rd] if best is not None else w[~keep]  # relative to the best
                acc[rd, 8:11] += vd[:, None] * c[~keep] * inv_gain
                acc[rd, 11] += vd
                acc[rd, 13] += 1.0
        del levels, ids, depth
    out = []
    for tx, acc in zip(pages, sums, strict=True):
        rows_h, cols_w = tx.shape
        flat = np.zeros((rows_h * cols_w, 14))
        flat[tx.index] = acc
        dense = flat.reshape(rows_h, cols_w, 14)
        out.append({"low": dense[..., 0:4], "detail": dense[..., 4:8], "dropped": dense[..., 8:12],
                    "counts": dense[..., 12:14]})
    return out
