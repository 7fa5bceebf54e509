"""Snapping a mark to the photo (issue "assisted marking"): a click near an image corner moves to
the corner's sub-pixel position (Förstner's least squares over the image gradients, as
``cv2.cornerSubPix``), a click near a straight edge moves onto the edge along its normal (the peak
of the directional derivative across it, to a fraction of a pixel by a parabola), and a drawn
segment is refined to the image line it covers (a line fitted to the edge points found along it,
both end points moved onto that line; its σ from the fit's scatter).

Snapping never moves a point more than :data:`SNAP_RADIUS_PX`; where it would, or where the photo
shows no edge there (a flat or noisy patch), the mark stays where it was clicked. Pixels follow
DESIGN.md: (u, v) from the image's top-left corner, the centre of pixel column i, row j at
(i + 0.5, j + 0.5). Plain numpy and OpenCV, no window.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: The farthest snapping moves a point (photo pixels): beyond it the mark stays where it was placed.
SNAP_RADIUS_PX = 3.0
#: The least gradient (grey levels of 255 per pixel, smoothed) that counts as an edge; a photo's
#: noise is well below it (JPEG noise of 2 grey levels gives smoothed gradients under 1).
MIN_GRADIENT = 6.0
#: A corner: the structure tensor's smaller eigenvalue at least this share of the larger (an edge's
#: is near 0, a right-angled corner's near 1).
CORNER_RATIO = 0.15
#: Half the side of the window a corner is refined over (pixels).
CORNER_HALF_PX = 8
#: The zone about a corner whose gradients are left out of its refinement (pixels).
CORNER_ZERO_PX = 3.5
#: Gaussian smoothing of the image before its gradients are taken (σ, pixels).
SMOOTH_SIGMA_PX = 0.8
#: Spacing of the edge points sampled along a drawn segment (pixels).
SEGMENT_STEP_PX = 2.0
#: Fewest edge points along a segment for a line fit (else the segment stays as drawn).
MIN_SEGMENT_POINTS = 5


@dataclass(frozen=True)
class Snap:
    """Where a point snapped: ``uv`` (photo pixels), ``kind`` (``corner`` or ``edge``), how far it
    moved (pixels), and ``sigma_px``, the 1σ of the snapped position (the largest direction)."""

    uv: tuple[float, float]
    kind: str
    moved_px: float
    sigma_px: float


@dataclass(frozen=True)
class SegmentFit:
    """A drawn segment refined to the image line it covers: its end points on the fitted line,
    ``sigma_px`` the 1σ of an end point across the line (from the fit's scatter), ``rms_px`` the
    scatter of the edge points about the line, ``points`` how many edge points it rests on, and
    ``moved_px`` the farthest an end point moved."""

    segment: tuple[float, float, float, float]
    sigma_px: float
    rms_px: float
    points: int
    moved_px: float


def grey(pixels: NDArray[np.generic]) -> NDArray[np.float32]:
    """A photo's (h, w, 3) or (h, w) pixels as float32 grey levels 0–255."""
    a = np.asarray(pixels)
    if a.ndim == 3:
        a = a[..., :3].astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
    return np.ascontiguousarray(a, np.float32)


def _patch(img: NDArray[np.float32], uv: Sequence[float], half: int) -> tuple[NDArray[np.float32], float, float] | None:
    """The smoothed patch of ``half`` pixels (+2 for the filters) around uv, and the uv of its first
    pixel's centre; None near the border."""
    import cv2

    cx, cy = int(math.floor(uv[0])), int(math.floor(uv[1]))
    h = half + 3
    y0, y1, x0, x1 = cy - h, cy + h + 1, cx - h, cx + h + 1
    if y0 < 0 or x0 < 0 or y1 > img.shape[0] or x1 > img.shape[1]:
        return None
    p = np.asarray(cv2.GaussianBlur(img[y0:y1, x0:x1], (0, 0), SMOOTH_SIGMA_PX), np.float32)
    return p, x0 + 0.5, y0 + 0.5


def _gradients(p: NDArray[np.float32]) -> tuple[Array, Array]:
    import cv2

    gx = np.asarray(cv2.Sobel(p, cv2.CV_64F, 1, 0, ksize=3), float) / 8.0
    gy = np.asarray(cv2.Sobel(p, cv2.CV_64F, 0, 1, ksize=3), float) / 8.0
    return gx, gy


def _bilinear(img: NDArray[np.float32], uv: Array) -> Array:
    """Grey levels at photo positions uv (n, 2), bilinear; the image's edge pixels beyond it."""
    x = np.clip(uv[:, 0] - 0.5, 0, img.shape[1] - 1.001)
    y = np.clip(uv[:, 1] - 0.5, 0, img.shape[0] - 1.001)
    i, j = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - i, y - j
    a = img[j, i] * (1 - fx) + img[j, i + 1] * fx
    b = img[j + 1, i] * (1 - fx) + img[j + 1, i + 1] * fx
    return np.asarray(a * (1 - fy) + b * fy, float)


def noise_sigma(img: NDArray[np.float32]) -> float:
    """The photo's noise, 1σ grey levels (Immerkær's fast estimate from a Laplacian-like filter)."""
    import cv2

    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    r = cv2.filter2D(img, cv2.CV_32F, kernel)[1:-1, 1:-1]
    return float(math.sqrt(math.pi / 2.0) * np.mean(np.abs(r)) / 6.0)


def snap_corner(img: NDArray[np.float32], uv: Sequence[float], radius: float = SNAP_RADIUS_PX,
                noise: float | None = None) -> Snap | None:
    """The image corner near uv, refined to a fraction of a pixel (Förstner: the point that the
    gradients' lines pass nearest, iterated about the new centre), or None where there is none within
    ``radius`` (an edge, a flat patch). ``noise``: the photo's 1σ grey levels (estimated if None)."""
    q = np.asarray(uv, float)
    sigma_n = noise_sigma(img) if noise is None else noise
    for _ in range(4):
        got = _patch(img, (float(q[0]), float(q[1])), CORNER_HALF_PX)
        if got is None:
            return None
        p, u0, v0 = got
        gx, gy = _gradients(p)
        c = slice(2, -2)
        gx, gy = gx[c, c], gy[c, c]
        uu, vv = np.meshgrid(u0 + 2 + np.arange(gx.shape[1]), v0 + 2 + np.arange(gx.shape[0]))
        r2 = (uu - q[0]) ** 2 + (vv - q[1]) ** 2
        # Gaussian weights, none within CORNER_ZERO_PX of the centre: there a blurred corner's
        # gradients turn and their lines miss the corner (cornerSubPix's "zero zone").
        w = np.exp(-r2 / (2.0 * (0.6 * CORNER_HALF_PX) ** 2)) * (r2 > CORNER_ZERO_PX**2)
        M = np.array([[np.sum(w * gx * gx), np.sum(w * gx * gy)], [np.sum(w * gx * gy), np.sum(w * gy * gy)]])
        ev = np.linalg.eigvalsh(M)
        if ev[1] <= np.sum(w) * MIN_GRADIENT**2 or ev[0] < CORNER_RATIO * ev[1]:
            return None
        b = np.array([np.sum(w * (gx * gx * uu + gx * gy * vv)), np.sum(w * (gx * gy * uu + gy * gy * vv))])
        new = np.linalg.solve(M, b)
        if not np.all(np.isfinite(new)) or np.linalg.norm(new - np.asarray(uv, float)) > radius:
            return None
        done = np.linalg.norm(new - q) < 1e-3
        q = new
        if done:
            break
    # Förstner's covariance: the scatter of the gradients' lines about the corner (each pixel's
    # g·(p − q), weighted) times M⁻¹; the photo's noise sets a floor on that scatter.
    r = gx * (uu - q[0]) + gy * (vv - q[1])
    s0 = float(np.sum(w * r * r) / max(float(np.sum(w > 0.05)) - 2.0, 1.0))
    s0 = max(s0, float(np.sum(w * (uu - q[0]) ** 2)) / max(float(np.sum(w)), 1e-9) * (0.18 * sigma_n) ** 2)
    cov = s0 * np.linalg.inv(M)
    s = float(math.sqrt(max(np.linalg.eigvalsh(cov)[1], 0.0)))
    moved = float(np.linalg.norm(q - np.asarray(uv, float)))
    return Snap((float(q[0]), float(q[1])), "corner", moved, s)


def _edge_along(img: NDArray[np.float32], uv: Array, n: Array, radius: float, tangent_half: float = 1.5,
                ) -> tuple[float, float] | None:
    """The edge across normal ``n`` through uv: the offset t (pixels along n) where the directional
    derivative peaks within ±radius, to a fraction of a pixel, and the peak (grey levels per
    pixel); None with no peak above :data:`MIN_GRADIENT` inside the range."""
    step = 0.25
    ts = np.arange(-radius - 1.0, radius + 1.0 + 1e-9, step)
    tang = np.array([-n[1], n[0]])
    offs = np.linspace(-tangent_half, tangent_half, 3)
    pts = uv[None, None, :] + ts[None, :, None] * n[None, None, :] + offs[:, None, None] * tang[None, None, :]
    prof = _bilinear(img, pts.reshape(-1, 2)).reshape(len(offs), len(ts)).mean(axis=0)
    d = np.gradient(prof, step)
    a = np.abs(d)
    inside = np.abs(ts) <= radius
    k = int(np.argmax(np.where(inside, a, -1.0)))
    if a[k] < MIN_GRADIENT or k == 0 or k == len(ts) - 1:
        return None
    # The centroid of the derivative's magnitude within 1.5 px of its peak: bilinear samples make the
    # peak a plateau a pixel wide, whose centre (not its highest sample) is the edge.
    near = np.abs(ts - ts[k]) <= 1.5
    wk = np.clip(a[near] - 0.5 * a[k], 0.0, None)
    t = float(np.sum(wk * ts[near]) / max(float(np.sum(wk)), 1e-12))
    y1 = a[k]
    if abs(t) > radius:
        return None
    return t, float(y1)


def snap_edge(img: NDArray[np.float32], uv: Sequence[float], radius: float = SNAP_RADIUS_PX,
              noise: float | None = None) -> Snap | None:
    """The point on the straight image edge near uv, moved along the edge's normal only (the
    gradient's direction there), or None where no edge is within ``radius``."""
    got = _patch(img, uv, 3)
    if got is None:
        return None
    p, _, _ = got
    gx, gy = _gradients(p)
    M = np.array([[np.sum(gx * gx), np.sum(gx * gy)], [np.sum(gx * gy), np.sum(gy * gy)]])
    ev, vec = np.linalg.eigh(M)
    if ev[1] <= gx.size * (0.5 * MIN_GRADIENT) ** 2:
        return None
    n = vec[:, 1]
    q = np.asarray(uv, float)
    found = _edge_along(img, q, n, radius)
    if found is None:
        return None
    t, peak = found
    sigma_n = noise_sigma(img) if noise is None else noise
    new = q + t * n
    # A blurred step's peak position: σ ≈ noise / (peak · sqrt(samples)) · the profile's width (≈ 1.5 px).
    s = float(1.5 * sigma_n / max(peak, 1e-6) / math.sqrt(3.0))
    return Snap((float(new[0]), float(new[1])), "edge", abs(t), s)


def snap_point(img: NDArray[np.float32], uv: Sequence[float], radius: float = SNAP_RADIUS_PX,
               noise: float | None = None) -> Snap | None:
    """A click snapped: to the corner near it if there is one, else to the edge near it, else None."""
    return snap_corner(img, uv, radius, noise) or snap_edge(img, uv, radius, noise)


def refine_segment(img: NDArray[np.float32], segment: Sequence[float], radius: float = SNAP_RADIUS_PX,
                   ) -> SegmentFit | None:
    """A drawn segment (u1, v1, u2, v2) refined to the image line it covers: edge points found across
    it every :data:`SEGMENT_STEP_PX` (within ``radius`` of it), a line fitted to them by total
    least squares (points beyond 3 robust σ dropped), both end points moved onto it along its normal.
    None where the segment covers no edge (too few edge points) or an end would move beyond
    ``radius``. The σ is that of an end point across the fitted line: the scatter about the line
    through the fit's covariance (at least a tenth of a pixel, which the image's own blur and
    aliasing leave)."""
    a, b = np.asarray(segment[:2], float), np.asarray(segment[2:4], float)
    L = float(np.linalg.norm(b - a))
    if L < 4.0 * SEGMENT_STEP_PX:
        return None
    d = (b - a) / L
    n = np.array([-d[1], d[0]])
    ts = np.arange(SEGMENT_STEP_PX, L - SEGMENT_STEP_PX + 1e-9, SEGMENT_STEP_PX)
    pts = []
    for t in ts:
        q = a + t * d
        found = _edge_along(img, q, n, radius)
        if found is not None:
            pts.append(q + found[0] * n)
    if len(pts) < MIN_SEGMENT_POINTS:
        return None
    P = np.asarray(pts)
    keep = np.ones(len(P), bool)
    for _ in range(3):
        c = P[keep].mean(axis=0)
        _, _, vt = np.linalg.svd(P[keep] - c)
        nn = vt[1]
        r = (P - c) @ nn
        mad = 1.4826 * float(np.median(np.abs(r[keep] - np.median(r[keep])))) + 0.02
        new_keep = np.abs(r) <= 3.0 * mad
        if new_keep.sum() < MIN_SEGMENT_POINTS or np.array_equal(new_keep, keep):
            break
        keep = new_keep
    c = P[keep].mean(axis=0)
    _, _, vt = np.linalg.svd(P[keep] - c)
    nn, dd = vt[1], vt[0]
    r = (P[keep] - c) @ nn
    m = int(keep.sum())
    rms = float(math.sqrt(np.sum(r**2) / max(m - 2, 1)))
    s_along = (P[keep] - c) @ dd

    def onto(p: Array) -> Array:
        return p - float((p - c) @ nn) * nn

    a2, b2 = onto(a), onto(b)
    moved = float(max(np.linalg.norm(a2 - a), np.linalg.norm(b2 - b)))
    if moved > radius:
        return None
    # An end at distance e from the fit's centre: var = rms² (1/m + e² / Σs²).
    e = max(abs(float((a - c) @ dd)), abs(float((b - c) @ dd)))
    sigma = float(max(rms * math.sqrt(1.0 / m + e**2 / max(float(np.sum(s_along**2)), 1e-9)), 0.1))
    return SegmentFit((float(a2[0]), float(a2[1]), float(b2[0]), float(b2[1])), sigma, rms, m, moved)
