"""Suggested correspondences between calibrated photos (issue "assisted marking"): feature points
(OpenCV's SIFT) matched across two photos (Lowe's ratio test, both ways) and kept only where the
two cameras' epipolar geometry allows them (the Sampson distance within a threshold made from the
cameras' own uncertainty, the point in front of both cameras within the plausible depths); a marker
placed in one photo found in another along its epipolar line (the best normalised correlation of
the patch about it, between the plausible depths); and a model vertex's image corner, near where
the model's vertex projects, for its pin.

Plain numpy and OpenCV, no window: the session (:mod:`vebuild.edit.assist`) turns what these find
into proposals the user accepts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, distort_pixels, pixel_rays_world, project, undistort_pixels, world_to_camera

from .snap import SNAP_RADIUS_PX, grey, snap_corner

Array = NDArray[np.float64]

#: Lowe's ratio test: the best match's descriptor distance below this share of the second best.
RATIO = 0.75
#: 1σ of a SIFT key point's position, pixels (its sub-pixel fit on a photo of ordinary noise).
FEATURE_SIGMA_PX = 0.7
#: The epipolar threshold: this many σ of the Sampson distance that the two positions' noise and the
#: cameras' uncertainty together give.
EPIPOLAR_SIGMAS = 3.0
#: The plausible depths of a point seen in a photo (metres, or the project's units): nearer than
#: the first is the lens, farther than the second is beyond any room or façade vebuild models.
DEPTH_RANGE_M = (0.2, 200.0)
#: The most matches kept per pair of photos (the best-spread ones: one per cell of a grid).
MAX_MATCHES = 40
#: Half the side of the patch correlated along an epipolar line (pixels).
PATCH_HALF_PX = 10
#: The least normalised correlation of a marker's patch for a proposal along its epipolar line.
MIN_NCC = 0.7
#: How far from a model vertex's projection its image corner is looked for (pixels).
PIN_SEARCH_PX = 12.0
#: The farthest from its prediction a triangulated marker is looked for (pixels).
MAX_PREDICTION_PX = 15.0
#: Most key points SIFT keeps per photo (its strongest).
MAX_FEATURES = 4000


@dataclass(frozen=True)
class Match:
    """A point seen at ``uv_a`` in photo a and ``uv_b`` in photo b, with its Sampson distance
    (pixels), the threshold it passed, its triangulated world point and the ratio test's ratio."""

    uv_a: tuple[float, float]
    uv_b: tuple[float, float]
    sampson_px: float
    threshold_px: float
    X: tuple[float, float, float]
    ratio: float


def fundamental(a: ImageCamera, b: ImageCamera) -> Array:
    """F with x_b^T F x_a = 0 for undistorted pixels (homogeneous) of the same world point seen by
    the calibrated cameras a and b (x = K R (X − C))."""
    R = b.R @ a.R.T
    t = b.R @ (np.asarray(a.C, float) - np.asarray(b.C, float))
    tx = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    F = np.linalg.inv(b.K).T @ tx @ R @ np.linalg.inv(a.K)
    return F / max(float(np.linalg.norm(F)), 1e-300)


def sampson(F: Array, uv_a: Array, uv_b: Array) -> Array:
    """The Sampson distance (pixels, first order of the reprojection distance) of pairs (n, 2)."""
    xa = np.c_[np.asarray(uv_a, float).reshape(-1, 2), np.ones(len(np.atleast_2d(uv_a)))]
    xb = np.c_[np.asarray(uv_b, float).reshape(-1, 2), np.ones(len(np.atleast_2d(uv_b)))]
    Fa, Ftb = xa @ F.T, xb @ F
    num = np.sum(xb * Fa, axis=1)
    den = Fa[:, 0] ** 2 + Fa[:, 1] ** 2 + Ftb[:, 0] ** 2 + Ftb[:, 1] ** 2
    return np.asarray(np.abs(num) / np.sqrt(np.maximum(den, 1e-300)), float)


def triangulate(a: ImageCamera, b: ImageCamera, uv_a: Array, uv_b: Array) -> Array:
    """World points (n, 3) nearest both rays (the midpoint of their common perpendicular)."""
    da = pixel_rays_world(a.K, a.R, np.asarray(uv_a, float).reshape(-1, 2), a.lens)
    db = pixel_rays_world(b.K, b.R, np.asarray(uv_b, float).reshape(-1, 2), b.lens)
    Ca, Cb = np.asarray(a.C, float), np.asarray(b.C, float)
    w = Ca - Cb
    A = np.sum(da * da, 1)
    B = np.sum(da * db, 1)
    Cc = np.sum(db * db, 1)
    D = np.sum(da * w, 1)
    E = np.sum(db * w, 1)
    den = np.maximum(A * Cc - B * B, 1e-12)
    s = (B * E - Cc * D) / den
    t = (A * E - B * D) / den
    return np.asarray(0.5 * ((Ca + s[:, None] * da) + (Cb + t[:, None] * db)), float)


def camera_sigma(cam: ImageCamera) -> tuple[float, float]:
    """The camera's rotation (radians) and position (metres) 1σ, the largest direction, from its
    covariance over (f, cx, cy, ω, C); (0, 0) for one given exactly."""
    cov = cam.covariance
    if cov is None or np.shape(cov) != (9, 9) or not np.all(np.isfinite(cov)):
        return 0.0, 0.0
    rot = float(math.sqrt(max(np.linalg.eigvalsh(np.asarray(cov)[3:6, 3:6])[-1], 0.0)))
    pos = float(math.sqrt(max(np.linalg.eigvalsh(np.asarray(cov)[6:9, 6:9])[-1], 0.0)))
    return rot, pos


def image_sigma(cam: ImageCamera, X: Sequence[float]) -> float:
    """The 1σ (pixels, the larger direction) of world point X's image that the camera's own
    uncertainty gives: its covariance over (f, cx, cy, ω, C) through the projection's Jacobian
    (pinhole; ω a small turn left-multiplied); 0 for a camera given exactly."""
    cov = cam.covariance
    if cov is None or np.shape(cov) != (9, 9) or not np.all(np.isfinite(cov)):
        return 0.0
    xc = np.asarray(cam.R, float) @ (np.asarray(X, float) - np.asarray(cam.C, float))
    if xc[2] <= 1e-9:
        return float("inf")
    f = float(cam.K[0, 0])
    A = f / xc[2] * np.array([[1.0, 0.0, -xc[0] / xc[2]], [0.0, 1.0, -xc[1] / xc[2]]])
    sx = np.array([[0.0, -xc[2], xc[1]], [xc[2], 0.0, -xc[0]], [-xc[1], xc[0], 0.0]])
    J = np.zeros((2, 9))
    J[:, 0] = xc[:2] / xc[2]
    J[:, 1:3] = np.eye(2)
    J[:, 3:6] = A @ (-sx)
    J[:, 6:9] = A @ (-np.asarray(cam.R, float))
    S = J @ np.asarray(cov, float) @ J.T
    return float(math.sqrt(max(np.linalg.eigvalsh(S)[-1], 0.0)))


def epipolar_threshold(a: ImageCamera, b: ImageCamera, X: Sequence[float], point_sigma_px: float = FEATURE_SIGMA_PX,
                       ) -> float:
    """The Sampson distance a true correspondence of world point X stays within (pixels):
    :data:`EPIPOLAR_SIGMAS` × the 1σ that the two positions' noise and the two cameras'
    uncertainty at X give (:func:`image_sigma`)."""
    var = 2.0 * point_sigma_px**2 + image_sigma(a, X) ** 2 + image_sigma(b, X) ** 2
    return EPIPOLAR_SIGMAS * math.sqrt(var)


def _features(img: NDArray[np.float32]) -> tuple[Array, NDArray[np.float32] | None]:
    import cv2

    sift = cv2.SIFT_create(nfeatures=MAX_FEATURES)  # type: ignore[attr-defined]
    kp, desc = sift.detectAndCompute(np.clip(img, 0, 255).astype(np.uint8), None)
    if desc is None or len(kp) == 0:
        return np.zeros((0, 2)), None
    uv = np.array([k.pt for k in kp], float) + 0.5  # OpenCV's pixel centres are integers
    return uv, desc


def _ratio_matches(da: NDArray[np.float32], db: NDArray[np.float32]) -> list[tuple[int, int, float]]:
    """Matches a→b passing the ratio test and mutual (b's best back is a)."""
    import cv2

    if len(da) < 2 or len(db) < 2:
        return []
    bf = cv2.BFMatcher(cv2.NORM_L2)
    ab = bf.knnMatch(da, db, k=2)
    ba = {m[0].queryIdx: m[0].trainIdx for m in bf.knnMatch(db, da, k=2) if m}
    out = []
    for pair in ab:
        if len(pair) < 2:
            continue
        m, n = pair
        ratio = m.distance / max(n.distance, 1e-9)
        if ratio < RATIO and ba.get(m.trainIdx) == m.queryIdx:
            out.append((m.queryIdx, m.trainIdx, float(ratio)))
    return out


def match_photos(pix_a: NDArray[np.generic], a: ImageCamera, pix_b: NDArray[np.generic], b: ImageCamera,
                 max_matches: int = MAX_MATCHES) -> tuple[list[Match], int]:
    """Feature points matched between two calibrated photos and checked against their epipolar
    geometry: the matches kept (best spread over photo a, at most ``max_matches``) and how many the
    epipolar and depth checks rejected. A photo with no features gives no matches."""
    ga, gb = grey(pix_a), grey(pix_b)
    uva, desca = _features(ga)
    uvb, descb = _features(gb)
    if desca is None or descb is None:
        return [], 0
    pairs = _ratio_matches(desca, descb)
    if not pairs:
        return [], 0
    ia = np.array([p[0] for p in pairs])
    ib = np.array([p[1] for p in pairs])
    ratios = np.array([p[2] for p in pairs])
    return check_matches(a, b, uva[ia], uvb[ib], ratios, max_matches)


def check_matches(a: ImageCamera, b: ImageCamera, uv_a: Array, uv_b: Array, ratios: Array | None = None,
                  max_matches: int = MAX_MATCHES) -> tuple[list[Match], int]:
    """The candidate pairs that the epipolar geometry of cameras a and b allows (see
    :func:`match_photos`), and how many it rejected."""
    uv_a, uv_b = np.asarray(uv_a, float).reshape(-1, 2), np.asarray(uv_b, float).reshape(-1, 2)
    if ratios is None:
        ratios = np.zeros(len(uv_a))
    if len(uv_a) == 0:
        return [], 0
    F = fundamental(a, b)
    ua, ub = undistort_pixels(a.K, uv_a, a.lens), undistort_pixels(b.K, uv_b, b.lens)
    d = sampson(F, ua, ub)
    X = triangulate(a, b, uv_a, uv_b)
    za = world_to_camera(a.R, a.C, X)[:, 2]
    zb = world_to_camera(b.R, b.C, X)[:, 2]
    lo, hi = DEPTH_RANGE_M
    thr = np.array([epipolar_threshold(a, b, x) if z > lo else 0.0 for x, z in zip(X, za, strict=True)])
    ok = (d <= thr) & (za > lo) & (zb > lo) & (za < hi) & (zb < hi)
    idx = np.flatnonzero(ok)
    # One per cell of an 8 × 8 grid over photo a (the lowest ratio), then the rest by ratio.
    cells: dict[tuple[int, int], int] = {}
    for i in idx[np.argsort(ratios[idx], kind="stable")]:
        key = (int(8 * uv_a[i, 0] / a.width), int(8 * uv_a[i, 1] / a.height))
        cells.setdefault(key, int(i))
    chosen = list(cells.values())
    rest = [int(i) for i in idx[np.argsort(ratios[idx], kind="stable")] if int(i) not in set(chosen)]
    chosen = (chosen + rest)[:max_matches]
    out = [Match((float(uv_a[i, 0]), float(uv_a[i, 1])), (float(uv_b[i, 0]), float(uv_b[i, 1])), float(d[i]),
                 float(thr[i]), (float(X[i, 0]), float(X[i, 1]), float(X[i, 2])), float(ratios[i])) for i in chosen]
    return out, int(len(uv_a) - int(ok.sum()))


def epipolar_curve(a: ImageCamera, uv_a: Sequence[float], b: ImageCamera,
                   depths: tuple[float, float] = DEPTH_RANGE_M, n: int = 400) -> tuple[Array, Array]:
    """Where the ray through uv_a in photo a projects into photo b between the two depths (along a's
    ray): (n, 2) pixels of b (through b's lens) and the depths, the points behind b or off its photo
    left out."""
    ray = pixel_rays_world(a.K, a.R, np.asarray(uv_a, float).reshape(1, 2), a.lens)[0]
    ray = ray / np.linalg.norm(ray)
    z_per_unit = float((a.R @ ray)[2])
    lo, hi = depths
    ds = np.geomspace(lo, hi, n) / max(z_per_unit, 1e-9)
    Xs = np.asarray(a.C, float)[None, :] + ds[:, None] * ray[None, :]
    front = world_to_camera(b.R, b.C, Xs)[:, 2] > 1e-6
    uv = project(b.K, b.R, b.C, Xs, b.lens)
    inside = front & (uv[:, 0] >= 0) & (uv[:, 1] >= 0) & (uv[:, 0] < b.width) & (uv[:, 1] < b.height)
    return uv[inside], ds[inside]


def _ncc(patch: Array, img: NDArray[np.float32], uv: Array, half: int) -> Array:
    """Normalised correlation of ``patch`` with the image's patches about each of uv (n, 2)."""
    from .snap import _bilinear

    off = np.arange(-half, half + 1, dtype=float)
    ox, oy = np.meshgrid(off, off)
    grid = np.c_[ox.ravel(), oy.ravel()]
    p = patch.ravel() - patch.mean()
    pn = float(np.linalg.norm(p))
    out = np.full(len(uv), -1.0)
    if pn < 1e-6:
        return out
    for k, q in enumerate(uv):
        v = _bilinear(img, q[None, :] + grid)
        v = v - v.mean()
        vn = float(np.linalg.norm(v))
        if vn > 1e-6:
            out[k] = float(p @ v) / (pn * vn)
    return out


def along_epipolar(pix_a: NDArray[np.generic], a: ImageCamera, uv_a: Sequence[float], pix_b: NDArray[np.generic],
                   b: ImageCamera, depths: tuple[float, float] = DEPTH_RANGE_M,
                   ) -> tuple[tuple[float, float], float, float] | None:
    """The point of photo b that a's point uv_a is, searched along its epipolar line between the
    plausible ``depths``: the best normalised correlation of the patch about uv_a (every half pixel
    along the line), refined to the image corner there if it is one. Returns (uv in b, the
    correlation, the depth along a's ray) or None (nothing correlates above :data:`MIN_NCC`; the
    line misses photo b)."""
    from .snap import _bilinear

    ga, gb = grey(pix_a), grey(pix_b)
    h = PATCH_HALF_PX
    off = np.arange(-h, h + 1, dtype=float)
    ox, oy = np.meshgrid(off, off)
    q = np.asarray(uv_a, float)
    if not (h <= q[0] < ga.shape[1] - h and h <= q[1] < ga.shape[0] - h):
        return None
    patch = _bilinear(ga, q[None, :] + np.c_[ox.ravel(), oy.ravel()]).reshape(ox.shape)
    uv, ds = epipolar_curve(a, (float(q[0]), float(q[1])), b, depths, n=2000)
    if len(uv) < 2:
        return None
    # Every half pixel along the curve.
    step = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(uv, axis=0), axis=1))]
    s = np.arange(0.0, step[-1], 0.5)
    pts = np.c_[np.interp(s, step, uv[:, 0]), np.interp(s, step, uv[:, 1])]
    dep = np.interp(s, step, ds)
    inside = (pts[:, 0] >= h) & (pts[:, 1] >= h) & (pts[:, 0] < gb.shape[1] - h) & (pts[:, 1] < gb.shape[0] - h)
    pts, dep = pts[inside], dep[inside]
    if len(pts) == 0:
        return None
    scores = _ncc(patch, gb, pts, h)
    k = int(np.argmax(scores))
    if scores[k] < MIN_NCC:
        return None
    best = pts[k]
    snap = snap_corner(gb, best, SNAP_RADIUS_PX)
    if snap is not None:
        best = np.asarray(snap.uv)
    return (float(best[0]), float(best[1])), float(scores[k]), float(dep[k])


def search_near(pix_src: NDArray[np.generic], uv_src: Sequence[float], pix_dst: NDArray[np.generic],
                uv_pred: Sequence[float], radius_px: float) -> tuple[tuple[float, float], float] | None:
    """The point of the destination photo within ``radius_px`` of its predicted position uv_pred
    whose patch correlates best with the source photo's patch about uv_src (OpenCV's normalised
    correlation, to a fraction of a pixel by a parabola, then to the image corner there if it is
    one): (uv, correlation), or None below :data:`MIN_NCC` or off the photo."""
    import cv2

    from .snap import _bilinear

    ga, gb = grey(pix_src), grey(pix_dst)
    h = PATCH_HALF_PX
    q = np.asarray(uv_src, float)
    if not (h <= q[0] < ga.shape[1] - h and h <= q[1] < ga.shape[0] - h):
        return None
    off = np.arange(-h, h + 1, dtype=float)
    ox, oy = np.meshgrid(off, off)
    tmpl = _bilinear(ga, q[None, :] + np.c_[ox.ravel(), oy.ravel()]).reshape(ox.shape).astype(np.float32)
    if float(tmpl.std()) < 1e-3:
        return None
    r = int(math.ceil(radius_px))
    cx, cy = int(math.floor(uv_pred[0])), int(math.floor(uv_pred[1]))  # the pixel whose centre is nearest
    x0, y0 = cx - r - h, cy - r - h
    x1, y1 = cx + r + h + 1, cy + r + h + 1
    if x0 < 0 or y0 < 0 or x1 > gb.shape[1] or y1 > gb.shape[0]:
        return None
    res = cv2.matchTemplate(np.ascontiguousarray(gb[y0:y1, x0:x1]), tmpl, cv2.TM_CCOEFF_NORMED)
    j, i = np.unravel_index(int(np.argmax(res)), res.shape)
    score = float(res[j, i])
    if score < MIN_NCC:
        return None
    du = dv = 0.0
    if 0 < i < res.shape[1] - 1:
        a, b, c = res[j, i - 1], res[j, i], res[j, i + 1]
        du = float(np.clip(0.5 * (a - c) / min(a - 2 * b + c, -1e-9), -0.5, 0.5))
    if 0 < j < res.shape[0] - 1:
        a, b, c = res[j - 1, i], res[j, i], res[j + 1, i]
        dv = float(np.clip(0.5 * (a - c) / min(a - 2 * b + c, -1e-9), -0.5, 0.5))
    # The template's centre pixel sits at (x0 + i + h, y0 + j + h); its centre at + 0.5; the source
    # point's offset from its own pixel centre carries over.
    frac = q - (np.floor(q) + 0.5)
    best = np.array([x0 + i + h + 0.5 + du, y0 + j + h + 0.5 + dv]) + frac
    snap = snap_corner(gb, best, SNAP_RADIUS_PX)
    if snap is not None:
        best = np.asarray(snap.uv)
    return (float(best[0]), float(best[1])), score


def prediction_radius(cam: ImageCamera, X: Sequence[float], point_sigma_px: float = FEATURE_SIGMA_PX) -> float:
    """How far from its predicted position a triangulated point may be seen in a photo (pixels):
    :data:`EPIPOLAR_SIGMAS` × the 1σ of the camera's rotation and position and of the two points it
    was triangulated from, at least 4 px and at most :data:`MAX_PREDICTION_PX` (beyond it a patch's
    correlation finds the wrong stripe of a wallpaper or tile of a floor as often as the right one:
    such a point is not proposed)."""
    s = math.sqrt(image_sigma(cam, X) ** 2 + 2.0 * point_sigma_px**2)
    return float(max(EPIPOLAR_SIGMAS * s, 4.0))


def pin_corner(pix: NDArray[np.generic], uv: Sequence[float], search_px: float = PIN_SEARCH_PX,
               ) -> tuple[float, float] | None:
    """The image corner nearest a model vertex's projection uv within ``search_px`` (OpenCV's
    Shi–Tomasi corners in the window, refined to a fraction of a pixel), or None."""
    import cv2

    g = grey(pix)
    r = int(math.ceil(search_px)) + 8
    cx, cy = int(uv[0]), int(uv[1])
    x0, y0 = max(cx - r, 0), max(cy - r, 0)
    x1, y1 = min(cx + r + 1, g.shape[1]), min(cy + r + 1, g.shape[0])
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    win = g[y0:y1, x0:x1]
    found = cv2.goodFeaturesToTrack(win, maxCorners=20, qualityLevel=0.05, minDistance=3, blockSize=5)
    if found is None:
        return None
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01)
    found = cv2.cornerSubPix(win, found.astype(np.float32), (4, 4), (1, 1), crit)  # junctions too
    pts = found.reshape(-1, 2).astype(float) + np.array([x0 + 0.5, y0 + 0.5])
    dist = np.linalg.norm(pts - np.asarray(uv, float), axis=1)
    order = np.argsort(dist)
    for i in order:
        if dist[i] > search_px:
            break
        return float(pts[i, 0]), float(pts[i, 1])
    return None


__all__ = ["Match", "along_epipolar", "camera_sigma", "check_matches", "distort_pixels", "epipolar_curve",
           "epipolar_threshold", "fundamental", "image_sigma", "match_photos", "pin_corner", "prediction_radius",
           "sampson", "search_near", "triangulate"]
