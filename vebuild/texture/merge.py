"""The merge (paper §4): per-texel sums → colours, fill of unseen texels, coverage maps (numpy).

Runs once, after every photo has been added on the GPU.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

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


def unseen_texels(coverage: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """Where a coverage map (h, w, 4) says no photo saw the texel (:data:`COVERAGE_UNSEEN`):
    on-face texels that were filled."""
    return np.all(np.asarray(coverage) == np.array(COVERAGE_UNSEEN, np.uint8), axis=-1)


def push_pull(colour: NDArray[np.floating[Any]], known: NDArray[np.bool_]) -> NDArray[np.floating[Any]]:
    """Fill the unknown texels of ``colour`` (h, w, 3) smoothly from the known ones (float32).

    Pull: halve the resolution repeatedly, averaging the known texels of each 2×2 block; push:
    from the coarsest level down, an unknown texel takes the (bilinearly) upsampled coarser value,
    so filled regions blend into their surroundings without a hard edge.
    """
    if known.all() or not known.any():
        return colour.copy()
    colour = np.asarray(colour, np.float32)
    levels = [(colour * known[..., None], known.astype(np.float32))]
    while max(levels[-1][1].shape) > 1:
        c, w = levels[-1]
        h2, w2 = (c.shape[0] + 1) // 2, (c.shape[1] + 1) // 2
        pc = np.zeros((2 * h2, 2 * w2, 3), np.float32)
        pw = np.zeros((2 * h2, 2 * w2), np.float32)
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


def _upsample(img: NDArray[np.floating[Any]], shape: tuple[int, int]) -> NDArray[np.floating[Any]]:
    """Bilinear 2× upsampling with texel centres aligned (weights ¾, ¼; edges clamped), cropped."""
    for axis in (0, 1):
        n = img.shape[axis]
        pad = [(0, 0)] * img.ndim
        pad[axis] = (1, 1)
        p = np.pad(img, pad, mode="edge")
        prev, mid, nxt = (np.take(p, np.arange(k, k + n), axis=axis) for k in range(3))
        even = 0.75 * mid + 0.25 * prev
        odd = 0.75 * mid + 0.25 * nxt
        img = np.stack([even, odd], axis=axis + 1).reshape(img.shape[:axis] + (2 * n,) + img.shape[axis + 1:])
    return img[: shape[0], : shape[1]]


def fill_page(colour: NDArray[np.uint8], seen: NDArray[np.bool_], face_map: NDArray[np.int32],
              faces: list[Face], fill: str, average_mode: bool) -> tuple[NDArray[np.uint8], dict[int, FaceStats]]:
    """Fill every chart of a page: its unseen texels, its off-face texels, its half of the gutter.

    ``colour`` (h, w, 3) is the merged sRGB page, ``seen`` where some photo saw a texel.
    ``fill`` 'push-pull' interpolates from the seen texels of the same face; 'average' uses the
    face's average colour (the paper). ``average_mode`` paints each face in its average colour
    (paper Figure 9, middle). A face no photo saw takes the average of its node's seen faces, or
    a dark grey. Averages are taken in linear light.
    """
    out = colour.astype(np.float32) / 255.0
    stats: dict[int, FaceStats] = {}
    pad = GUTTER // 2
    todo = []
    for f in faces:
        x0, y0, w, h = f.rect
        sl = (slice(y0, y0 + h), slice(x0, x0 + w))
        on = face_map[sl] == f.id
        known = seen[sl] & on
        mean = srgb8_to_linear(colour[sl][known]).mean(axis=0) if known.any() else np.full(3, np.nan)
        stats[f.id] = FaceStats(float(known.sum() / max(1, on.sum())), int(on.sum()), mean)
        todo.append((f, sl, known, mean))
    by_node: dict[str, list[Array]] = {}
    for f, _, known, mean in todo:
        if known.any():
            by_node.setdefault(f.node, []).append(mean)
    for f, sl, known, mean in todo:
        if not known.any():
            fallback = np.mean(by_node[f.node], axis=0) if f.node in by_node else np.full(3, UNSEEN_GREY)
            out[sl] = _srgb(fallback)
        elif average_mode:
            out[sl] = _srgb(mean)
        elif not known.all():
            out[sl] = push_pull(out[sl], known) if fill == "push-pull" else np.where(known[..., None], out[sl],
                                                                                     _srgb(mean))
    # Bleed each chart into its half of the gutter so filtering never reaches a neighbour.
    for f in faces:
        x0, y0, w, h = f.rect
        chart = out[y0:y0 + h, x0:x0 + w]
        out[y0 - pad:y0 + h + pad, x0 - pad:x0 + w + pad] = np.pad(chart, ((pad, pad), (pad, pad), (0, 0)), mode="edge")
    np.clip(out, 0.0, 1.0, out=out)  # in place: a page's float copy is 12 bytes a texel
    out *= 255.0
    np.rint(out, out=out)
    return out.astype(np.uint8), stats


def _srgb(linear: Array) -> NDArray[np.float32]:
    return (linear_to_srgb8(linear).astype(np.float32) / 255.0)


def linear_to_srgb8(c: Array) -> NDArray[np.uint8]:
    """Linear [0, 1] → 8-bit sRGB (IEC 61966-2-1)."""
    c = np.clip(c, 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.rint(s * 255.0).astype(np.uint8)


def _srgb8_to_linear(s: NDArray[Any]) -> Array:
    c = np.asarray(s, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


#: :func:`srgb8_to_linear` of each 8-bit level, looked up for uint8 input: the same values, some
#: twenty times faster than the power law on a photo.
_SRGB8_LINEAR = _srgb8_to_linear(np.arange(256, dtype=np.uint8))


def srgb8_to_linear(s: NDArray[np.uint8]) -> Array:
    """8-bit sRGB → linear [0, 1] (IEC 61966-2-1)."""
    a = np.asarray(s)
    return _SRGB8_LINEAR[a] if a.dtype == np.uint8 else _srgb8_to_linear(a)
