"""The merge (paper §4): per-texel sums → colours, fill of unseen texels, coverage maps (numpy).

Runs once, after every photo has been added on the GPU.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from vebuild.texture.layout import GUTTER, Face

Array = NDArray[np.float64]

#: Coverage map colours (RGBA): texels no photo saw (filled), seen only by views far worse than the
#: best (kept as a last resort), and seen by 1, 2, 3, ≥ 4 photos. Off-face texels are transparent.
COVERAGE_UNSEEN = (255, 0, 255, 255)
COVERAGE_DROPPED_ONLY = (128, 128, 128, 255)
COVERAGE_VIEWS = ((215, 48, 39, 255), (252, 141, 89, 255), (145, 207, 96, 255), (26, 152, 80, 255))
#: Linear grey for a face that no photo saw, when its node has no seen face to borrow from.
UNSEEN_GREY = 0.2


@dataclass
class FaceStats:
    seen_fraction: float  # share of the face's texels some photo saw
    texels: int  # texels on the face
    mean_linear: Array  # (3,) weighted mean linear colour of the seen texels (nan if none)


def colours(sums: dict[str, NDArray[np.float32]],
            exposure_scale: float = 1.0) -> tuple[Array, NDArray[np.bool_], Array]:
    """Merged linear colour (h, w, 3), seen mask and weight (h, w) of one page's sums."""
    low, detail, dropped = (sums[k].astype(np.float64) for k in ("low", "detail", "dropped"))
    kept = low[..., 3] > 0
    only_dropped = ~kept & (dropped[..., 3] > 0)
    out = np.zeros(low.shape[:2] + (3,))
    out[kept] = low[kept, :3] / low[kept, 3:4]
    has_detail = kept & (detail[..., 3] > 0)
    out[has_detail] += detail[has_detail, :3] / detail[has_detail, 3:4]
    out[only_dropped] = dropped[only_dropped, :3] / dropped[only_dropped, 3:4]
    weight = np.where(kept, low[..., 3], dropped[..., 3])
    return np.clip(out * exposure_scale, 0.0, 1.0), kept | only_dropped, weight


def push_pull(colour: Array, known: NDArray[np.bool_]) -> Array:
    """Fill the unknown texels of ``colour`` (h, w, 3) smoothly from the known ones.

    Pull: halve the resolution repeatedly, averaging the known texels of each 2×2 block; push:
    from the coarsest level down, an unknown texel takes the (bilinearly) upsampled coarser value,
    so filled regions blend into their surroundings without a hard edge.
    """
    if known.all() or not known.any():
        return colour.copy()
    levels = [(colour * known[..., None], known.astype(np.float64))]
    while max(levels[-1][1].shape) > 1:
        c, w = levels[-1]
        h2, w2 = (c.shape[0] + 1) // 2, (c.shape[1] + 1) // 2
        pc = np.zeros((2 * h2, 2 * w2, 3))
        pw = np.zeros((2 * h2, 2 * w2))
        pc[: c.shape[0], : c.shape[1]], pw[: w.shape[0], : w.shape[1]] = c, w
        levels.append((pc.reshape(h2, 2, w2, 2, 3).sum(axis=(1, 3)), pw.reshape(h2, 2, w2, 2).sum(axis=(1, 3))))
    c, w = levels[-1]
    filled = c / np.maximum(w, 1e-12)[..., None]
    for c, w in reversed(levels[:-1]):
        up = _upsample(filled, c.shape[:2])
        mean = c / np.maximum(w, 1e-12)[..., None]
        alpha = np.minimum(w, 1.0)[..., None]  # a block with any known texel keeps its own mean
        filled = alpha * mean + (1.0 - alpha) * up
    return np.where(known[..., None], colour, filled)


def _upsample(img: Array, shape: tuple[int, int]) -> Array:
    """Bilinear 2× upsampling (texel centres aligned), cropped to ``shape``."""
    h, w = img.shape[:2]
    ys = np.clip((np.arange(shape[0]) + 0.5) / 2.0 - 0.5, 0, h - 1)
    xs = np.clip((np.arange(shape[1]) + 0.5) / 2.0 - 0.5, 0, w - 1)
    y0, x0 = np.floor(ys).astype(int), np.floor(xs).astype(int)
    y1, x1 = np.minimum(y0 + 1, h - 1), np.minimum(x0 + 1, w - 1)
    fy, fx = (ys - y0)[:, None, None], (xs - x0)[None, :, None]
    top = img[y0][:, x0] * (1 - fx) + img[y0][:, x1] * fx
    bottom = img[y1][:, x0] * (1 - fx) + img[y1][:, x1] * fx
    return top * (1 - fy) + bottom * fy


def fill_page(colour: Array, seen: NDArray[np.bool_], weight: Array, face_map: NDArray[np.int32],
              faces: list[Face], fill: str, average_mode: bool) -> tuple[Array, dict[int, FaceStats]]:
    """Fill every chart of a page (unseen texels, off-face texels, its half of the gutter).

    ``fill`` 'push-pull' interpolates from the seen texels; 'average' uses the face's average colour
    (the paper). ``average_mode`` paints each face in its average colour (paper Figure 9, middle).
    """
    out = np.zeros_like(colour)
    stats: dict[int, FaceStats] = {}
    pad = GUTTER // 2
    for f in faces:
        x0, y0, w, h = f.rect
        sl = (slice(y0, y0 + h), slice(x0, x0 + w))
        on = face_map[sl] == f.id
        known = seen[sl] & on
        c = colour[sl]
        wt = weight[sl] * known
        mean = (c * wt[..., None]).sum(axis=(0, 1)) / wt.sum() if wt.sum() > 0 else np.full(3, np.nan)
        stats[f.id] = FaceStats(float(known.sum() / max(1, on.sum())), int(on.sum()), mean)
        if not known.any():
            chart = None  # filled below from the node's other faces
        elif average_mode or fill == "average":
            chart = np.where(known[..., None] & (not average_mode), c, mean)
        else:
            chart = push_pull(c, known)
        if chart is not None:
            out[sl] = chart
    # Faces no photo saw: the seen-weighted mean of their node's other faces, else a dark grey.
    by_node: dict[str, list[Array]] = {}
    for f in faces:
        if np.isfinite(stats[f.id].mean_linear).all():
            by_node.setdefault(f.node, []).append(stats[f.id].mean_linear)
    for f in faces:
        if not np.isfinite(stats[f.id].mean_linear).all():
            x0, y0, w, h = f.rect
            fallback = np.mean(by_node[f.node], axis=0) if f.node in by_node else np.full(3, UNSEEN_GREY)
            out[y0:y0 + h, x0:x0 + w] = fallback
    # Bleed each chart into its half of the gutter so filtering never reaches a neighbour.
    for f in faces:
        x0, y0, w, h = f.rect
        chart = out[y0:y0 + h, x0:x0 + w]
        out[y0 - pad:y0 + h + pad, x0 - pad:x0 + w + pad] = np.pad(chart, ((pad, pad), (pad, pad), (0, 0)), mode="edge")
    return out, stats


def coverage_image(counts: NDArray[np.float32], seen: NDArray[np.bool_],
                   face_map: NDArray[np.int32]) -> NDArray[np.uint8]:
    """RGBA coverage map of a page (colours: COVERAGE_*)."""
    kept = np.rint(counts[..., 0]).astype(int)
    out = np.zeros(face_map.shape + (4,), np.uint8)
    on = face_map > 0
    out[on & ~seen] = COVERAGE_UNSEEN
    out[on & seen & (kept == 0)] = COVERAGE_DROPPED_ONLY
    for n, rgba in enumerate(COVERAGE_VIEWS, start=1):
        sel = on & seen & ((kept == n) if n < len(COVERAGE_VIEWS) else (kept >= n))
        out[sel] = rgba
    return out


def linear_to_srgb8(c: Array) -> NDArray[np.uint8]:
    """Linear [0, 1] → 8-bit sRGB (IEC 61966-2-1)."""
    c = np.clip(c, 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.rint(s * 255.0).astype(np.uint8)


def srgb8_to_linear(s: NDArray[np.uint8]) -> Array:
    c = np.asarray(s, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def erode_known(known: NDArray[np.bool_], texels: int) -> NDArray[np.bool_]:
    """``known`` shrunk by ``texels`` (for measurements away from a chart's border)."""
    return ndimage.binary_erosion(known, iterations=texels) if texels > 0 else known
