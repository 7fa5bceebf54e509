"""Straight image edges and their grouping into three orthogonal vanishing directions.

Pure functions over a photo's grey pixels (numpy; OpenCV's LSD detector); no project, no I/O.

**Detection** (:func:`detect_lines`). LSD (von Gioi et al., IPOL 2012, as OpenCV ships it) runs on
a pyramid level whose longer side is at most :data:`DETECT_LONG_SIDE` px (a 12 MP photo is halved:
a quarter of the pixels, the edges a photo of a room is marked on are long). Each segment is then
refined on the *full-resolution* image: at :data:`REFINE_SAMPLES` places along it the intensity
profile across it (±:data:`PROFILE_HALF_PX` px, bilinear) is differentiated and its extremum located
to a fraction of a pixel (parabola through the three samples around it); a line is fitted to those
edge points (total least squares), and the end points are LSD's projected on it. The end points'
1σ across the line is the fit's: with s the RMS residual of n edge points spread over the
segment, the offset of the fitted line at an end has variance s² (1/n + (t − t̄)²/Σ(tᵢ − t̄)²),
floored at :data:`SIGMA_FLOOR_PX` (what a straight-line model of a real edge, JPEG blocks and
the lens's residual curvature can promise). A segment whose profile has no clear edge at most
places, or whose edge points do not fit a line, is dropped.

**Grouping** (:func:`group_manhattan`). A RANSAC over Manhattan frames: a hypothesis is a focal
length f (principal point at the image centre) and three orthogonal directions. Either four
segments (two meeting at v₁, two at v₂; f² = −(v₁ − c)·(v₂ − c) from orthogonality), or two
segments (v₁) with a third (v₂ ⟂ v₁ on it) and f drawn from the EXIF prior (or log-uniform over
:data:`FOCAL_RANGE_REL`, 0.3–6 × the longer side, where EXIF is silent). A hypothesis scores the
summed length of the segments whose end points lie within :data:`INLIER_PX` of the line through
their midpoint and one of its vanishing points. The best is refined (f and R by robust least
squares on those distances, with the EXIF focal prior), inliers re-assigned, refined again. Where
the edges show one direction only, :func:`single_vanishing_point` finds the one point most of
them meet at.

**Axes** (:func:`orient_axes`): z is the direction nearest the image's vertical (photos are
decoded as displayed, EXIF orientation applied), signed so that world z points up (v decreases
upward). Of the two horizontal directions, ``x_axis`` chooses world x: ``right`` (default) the one
whose image direction is the more horizontal, pointing right; ``left`` the same pointing left;
``away`` the one nearer the optical axis, pointing away from the camera; ``toward`` the same
pointing toward it. y = z × x (right-handed). Each segment is then directed toward the positive
end of its axis (DESIGN.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import map_coordinates
from scipy.optimize import least_squares

Array = NDArray[np.float64]

#: The pyramid level LSD runs on has a longer side of at most this many pixels.
DETECT_LONG_SIDE = 2048
#: Shortest segment kept, as a fraction of the photo's longer side (and at least 12 px).
MIN_LENGTH_REL = 0.02
#: Places along a segment where its edge is refined on the full-resolution image.
REFINE_SAMPLES = 24
#: Half-width of the intensity profile taken across a segment, full-resolution pixels.
PROFILE_HALF_PX = 3.0
#: Points of the polyline a detected segment is written as (its bend measures the lens distortion).
POLYLINE_POINTS = 4
#: Floor of a detected end point's 1σ, pixels (see the module docstring).
SIGMA_FLOOR_PX = 0.3
#: Most segments grouped (the longest).
MAX_SEGMENTS = 600
#: A segment agrees with a vanishing point where its end points lie within this distance of the
#: line through its midpoint and the point (pixels, at the photo's full resolution; scaled with
#: the photo's size from a 2000-pixel side).
INLIER_PX = 1.5
#: RANSAC hypotheses per photo.
RANSAC_ITERATIONS = 1500
#: Range of focal lengths (× the longer side) hypotheses and estimates may take.
FOCAL_RANGE_REL = (0.3, 6.0)
#: The choices of world x (module docstring).
X_AXIS_CHOICES = ("right", "left", "away", "toward")
#: A photo darker than this mean grey level (0–255) with too few segments is "too dark".
DARK_MEAN_GREY = 12.0


@dataclass(frozen=True)
class DetectedLines:
    """Refined straight segments of one photo (full-resolution pixels, as the lens put them).

    segments : (n, 4) u1, v1, u2, v2 (undirected).
    sigma_px : (n,) 1σ of each segment's end points across the line.
    level_scale : full-resolution pixels per pixel of the level LSD ran on.
    mean_grey : the photo's mean grey level (0–255).
    polylines : (n, 2 POLYLINE_POINTS) each segment as the centroids of its edge points in
        POLYLINE_POINTS equal stretches along it, in the order of ``segments``' end points.
    polyline_sigma_px : (n,) 1σ across the line of each polyline point.
    """

    segments: Array
    sigma_px: Array
    level_scale: float
    mean_grey: float
    polylines: Array
    polyline_sigma_px: Array


@dataclass(frozen=True)
class ManhattanFrame:
    """Three orthogonal vanishing directions, the focal length and each segment's axis.

    directions : (3, 3) columns the unit directions in camera coordinates (undirected before
        :func:`orient_axes`; its columns world x, y, z after).
    focal_px : the focal length found (principal point at the image centre).
    focal_sigma_px : its 1σ from the refinement (inf where the segments do not determine it).
    labels : (n,) 0, 1, 2 the direction each segment agrees with, −1 none.
    residual_px : (n,) the RMS distance of each segment's end points to its line through the
        vanishing point (pixels; inf where unlabelled).
    """

    directions: Array
    focal_px: float
    focal_sigma_px: float
    labels: NDArray[np.int64]
    residual_px: Array


def to_grey(pixels: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """(h, w, 3) RGB or (h, w) grey → (h, w) uint8 grey (Rec. 601 luma, OpenCV's)."""
    import cv2

    if pixels.ndim == 2:
        return np.ascontiguousarray(pixels, np.uint8)
    return np.asarray(cv2.cvtColor(np.ascontiguousarray(pixels, np.uint8), cv2.COLOR_RGB2GRAY), np.uint8)


def detect_lines(grey: NDArray[np.uint8], *, long_side: int = DETECT_LONG_SIDE) -> DetectedLines:
    """LSD segments of a grey image, refined to sub-pixel end points on the full resolution."""
    import cv2

    h, w = grey.shape
    scale = max(1.0, max(w, h) / long_side)
    g8 = np.ascontiguousarray(np.clip(grey, 0, 255), np.uint8) if grey.dtype != np.uint8 else grey
    level = g8 if scale == 1.0 else cv2.resize(g8, (max(1, round(w / scale)), max(1, round(h / scale))),
                                               interpolation=cv2.INTER_AREA)
    sx, sy = w / level.shape[1], h / level.shape[0]
    lsd = cv2.createLineSegmentDetector(cv2.LSD_REFINE_NONE)
    found = lsd.detect(level)[0]
    mean_grey = float(np.mean(level))
    if found is None or len(found) == 0:
        return DetectedLines(np.zeros((0, 4)), np.zeros(0), scale, mean_grey,
                             np.zeros((0, 2 * POLYLINE_POINTS)), np.zeros(0))
    s = found.reshape(-1, 4).astype(float) * np.array([sx, sy, sx, sy])
    length = np.hypot(s[:, 2] - s[:, 0], s[:, 3] - s[:, 1])
    keep = length >= max(12.0, MIN_LENGTH_REL * max(w, h))
    s, length = s[keep], length[keep]
    order = np.argsort(-length)[: 2 * MAX_SEGMENTS]
    s = s[order]
    segs, sig, polys, psig = refine_segments(grey, s)
    return DetectedLines(segs, sig, scale, mean_grey, polys, psig)


def refine_segments(grey: NDArray[np.uint8], s: Array) -> tuple[Array, Array, Array, Array]:
    """Each segment (n, 4) refined on the image's intensity profiles across it (module docstring):
    the kept segments, their end points' 1σ, their polylines (m, 2 POLYLINE_POINTS) and the 1σ of
    each polyline point."""
    n = len(s)
    if n == 0:
        return np.zeros((0, 4)), np.zeros(0), np.zeros((0, 2 * POLYLINE_POINTS)), np.zeros(0)
    a, b = s[:, :2], s[:, 2:]
    d = b - a
    L = np.linalg.norm(d, axis=1)
    t_dir = d / L[:, None]
    nrm = np.stack([-t_dir[:, 1], t_dir[:, 0]], axis=1)
    # Sample positions along each segment (avoiding the ends, where corners blur the edge).
    ts = np.linspace(0.08, 0.92, REFINE_SAMPLES)
    offs = np.arange(-PROFILE_HALF_PX, PROFILE_HALF_PX + 0.5, 0.5)
    P = a[:, None, :] + ts[None, :, None] * d[:, None, :]  # (n, m, 2)
    Q = P[:, :, None, :] + offs[None, None, :, None] * nrm[:, None, None, :]  # (n, m, k, 2)
    # map_coordinates takes (row, col) of pixel centres: pixel (u, v) sits at column u − 0.5.
    coords = np.stack([Q[..., 1].ravel() - 0.5, Q[..., 0].ravel() - 0.5])
    prof = map_coordinates(grey, coords, order=1, mode="nearest", output=np.float32).reshape(Q.shape[:3])
    grad = np.abs(np.diff(prof, axis=2))  # between samples: offsets offs[:-1] + 0.25
    k = grad.shape[2]
    j = np.argmax(grad[:, :, 1:-1], axis=2) + 1
    g0 = np.take_along_axis(grad, (j - 1)[..., None], 2)[..., 0]
    g1 = np.take_along_axis(grad, j[..., None], 2)[..., 0]
    g2 = np.take_along_axis(grad, (j + 1)[..., None], 2)[..., 0]
    den = g0 - 2 * g1 + g2
    frac = np.where(den < 0, 0.5 * (g0 - g2) / np.where(den < 0, den, -1.0), 0.0)
    frac = np.clip(frac, -0.5, 0.5)
    off = offs[0] + 0.25 + 0.5 * (j + frac)
    # A clear edge: its gradient stands out of the profile's (and is not at the window's rim).
    strong = (g1 > 2.0) & (g1 > 2.0 * np.median(grad, axis=2)) & (j > 0) & (j < k - 1)
    E = P + off[..., None] * nrm[:, None, :]  # (n, m, 2) edge points
    out: list[Array] = []
    sig: list[float] = []
    polys: list[Array] = []
    psig: list[float] = []
    for i in range(n):
        ok = strong[i]
        if ok.sum() < max(6, REFINE_SAMPLES // 2):
            continue
        pts = E[i, ok]
        c = pts.mean(axis=0)
        _, sv, vt = np.linalg.svd(pts - c, full_matrices=False)
        direction = vt[0]
        normal = vt[1]
        r = (pts - c) @ normal
        m = len(r)
        res_rms = float(np.sqrt(np.sum(r**2) / max(m - 2, 1)))
        if res_rms > 1.0:  # not straight: a curve, a texture, two edges
            continue
        # Outliers (a blob crossing the edge): refit without points beyond 3 RMS.
        good = np.abs(r) <= max(3 * res_rms, 0.05)
        if good.sum() >= 6 and good.sum() < m:
            pts = pts[good]
            c = pts.mean(axis=0)
            _, _, vt = np.linalg.svd(pts - c, full_matrices=False)
            direction, normal = vt[0], vt[1]
            r = (pts - c) @ normal
            m = len(r)
            res_rms = float(np.sqrt(np.sum(r**2) / max(m - 2, 1)))
        tt = (pts - c) @ direction
        ta, tb = (a[i] - c) @ direction, (b[i] - c) @ direction
        spread = max(float(np.sum((tt - tt.mean()) ** 2)), 1e-9)
        var_end = res_rms**2 * (1.0 / m + max((ta - tt.mean()) ** 2, (tb - tt.mean()) ** 2) / spread)
        # The polyline: the centroids of the edge points of each of POLYLINE_POINTS stretches, in
        # order along the segment (real edge positions: their bend measures the lens distortion).
        order = np.argsort(tt)
        groups = np.array_split(order, POLYLINE_POINTS)
        if min(len(g) for g in groups) < 2:
            continue
        poly = np.concatenate([pts[g].mean(axis=0) for g in groups])
        if (tb - ta) * (tt[order[-1]] - tt[order[0]]) < 0:
            poly = poly.reshape(-1, 2)[::-1].ravel()
        out.append(np.r_[c + ta * direction, c + tb * direction])
        sig.append(max(float(np.sqrt(var_end)), SIGMA_FLOOR_PX))
        polys.append(poly)
        psig.append(max(res_rms / np.sqrt(min(len(g) for g in groups)), SIGMA_FLOOR_PX))
    if not out:
        return np.zeros((0, 4)), np.zeros(0), np.zeros((0, 2 * POLYLINE_POINTS)), np.zeros(0)
    return np.array(out), np.array(sig), np.array(polys), np.array(psig)


# --------------------------------------------------------------------------------------------------
# Grouping


def _distances(segs: Array, V: Array) -> Array:
    """(n, k) RMS distance of each segment's end points to the line through its midpoint and each
    homogeneous vanishing point (columns of V, (3, k))."""
    m = 0.5 * (segs[:, :2] + segs[:, 2:])
    half = 0.5 * (segs[:, 2:] - segs[:, :2])
    # Line through m and v: l = (m, 1) × v; distance of m + half to it = |l·(half, 0)| / |l_xy|.
    l0 = m[:, 1:2] * V[2][None] - V[1][None]
    l1 = V[0][None] - m[:, 0:1] * V[2][None]
    num = np.abs(l0 * half[:, 0:1] + l1 * half[:, 1:2])
    return np.asarray(num / np.maximum(np.hypot(l0, l1), 1e-300), float)


def _normals(segs: Array, f: float, c: Array) -> Array:
    """Unit normals (n, 3), camera coordinates, of the planes through the camera and each segment."""
    p1 = np.c_[(segs[:, :2] - c) / f, np.ones(len(segs))]
    p2 = np.c_[(segs[:, 2:] - c) / f, np.ones(len(segs))]
    n = np.cross(p1, p2)
    return np.asarray(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300), float)


def _frame_from(d1: Array, d2: Array) -> Array | None:
    n1 = np.linalg.norm(d1)
    if n1 < 1e-12:
        return None
    d1 = d1 / n1
    d2 = d2 - d1 * (d1 @ d2)
    n2 = np.linalg.norm(d2)
    if n2 < 1e-12:
        return None
    d2 = d2 / n2
    return np.column_stack([d1, d2, np.cross(d1, d2)])


def _score(segs: Array, length: Array, D: Array, f: float, c: Array, thr: float) -> tuple[float, Array, Array]:
    K = np.array([[f, 0, c[0]], [0, f, c[1]], [0, 0, 1.0]])
    dist = _distances(segs, K @ D)
    lab = np.argmin(dist, axis=1)
    best = dist[np.arange(len(segs)), lab]
    ok = best < thr
    return float(np.sum(length[ok] * (1.0 - (best[ok] / thr) ** 2))), np.where(ok, lab, -1), best


def group_manhattan(segments: Array, width: int, height: int, *, focal_prior: tuple[float, float] | None = None,
                    seed: int = 0, iterations: int = RANSAC_ITERATIONS,
                    sigma_px: Array | None = None) -> ManhattanFrame | None:
    """Three orthogonal vanishing directions of undistorted segments (n, 4), or None where fewer
    than two directions are found. ``focal_prior``: (f, 1σ) pixels, EXIF's."""
    n = len(segments)
    if n < 4:
        return None
    rng = np.random.default_rng(seed)
    c = np.array([width / 2.0, height / 2.0])
    side = float(max(width, height))
    thr = INLIER_PX * max(1.0, side / 2000.0)
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    order = np.argsort(-length)[:MAX_SEGMENTS]
    segs, ln = segments[order], length[order]
    n = len(segs)
    p = ln / ln.sum()
    fmin, fmax = FOCAL_RANGE_REL[0] * side, FOCAL_RANGE_REL[1] * side
    Ds, fs = _hypotheses(rng, segs, p, c, fmin, fmax, focal_prior, iterations)
    best: tuple[float, Array, float] | None = None
    for b0 in range(0, len(fs), 256):
        sc = _batch_scores(segs, ln, Ds[b0:b0 + 256], fs[b0:b0 + 256], c, thr)
        k = int(np.argmax(sc))
        if best is None or sc[k] > best[0]:
            best = (float(sc[k]), Ds[b0 + k], float(fs[b0 + k]))
    if best is None:
        return None
    _, D, f = best
    f_sigma = np.inf
    for _ in range(3):
        _, lab, _ = _score(segs, ln, D, f, c, thr * 2)
        sig = sigma_px[order] if sigma_px is not None else None
        D, f, f_sigma = _refine(segs, lab, D, f, c, focal_prior, fmin, fmax, sig)
    _, lab, dist = _score(segs, ln, D, f, c, thr)
    counts = np.bincount(lab[lab >= 0], minlength=3)
    if np.sum(counts >= 2) < 2:
        return None
    labels = np.full(len(segments), -1, dtype=np.int64)
    labels[order] = lab
    resid = np.full(len(segments), np.inf)
    resid[order] = np.where(lab >= 0, dist, np.inf)
    return ManhattanFrame(D, f, f_sigma, labels, resid)


#: RANSAC hypotheses (pairs of segments) for :func:`single_vanishing_point`.
SINGLE_ITERATIONS = 400


def single_vanishing_point(segments: Array, width: int, height: int, *, seed: int = 0,
                           iterations: int = SINGLE_ITERATIONS) -> tuple[Array, NDArray[np.bool_]] | None:
    """The one vanishing point that most of the undistorted segments (n, 4) agree with, for a photo
    whose edges show one direction only: a RANSAC over pairs of segments (their lines' meeting
    point), scored as :func:`group_manhattan` scores a frame (summed length within
    :data:`INLIER_PX`, truncated quadratic), then the best-fit point of the agreeing segments
    (:func:`vebuild.calibration.vanishing.fit_vanishing_point`, at infinity too), re-assigned and
    fitted once more. Returns the point (3,), homogeneous pixels, and which segments agree; None
    where fewer than two agree. No focal length enters: the point is the image's."""
    from vebuild.errors import VebuildError

    from .vanishing import fit_vanishing_point

    n = len(segments)
    if n < 2:
        return None
    rng = np.random.default_rng(seed)
    side = float(max(width, height))
    thr = INLIER_PX * max(1.0, side / 2000.0)
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    order = np.argsort(-length)[:MAX_SEGMENTS]
    segs, ln = segments[order], length[order]
    lines = np.cross(np.c_[segs[:, :2], np.ones(len(segs))], np.c_[segs[:, 2:], np.ones(len(segs))])
    idx = _distinct(rng.choice(len(segs), (iterations, 2), p=ln / ln.sum()))
    V = np.cross(lines[idx[:, 0]], lines[idx[:, 1]]).T  # (3, H)
    V = V[:, np.linalg.norm(V, axis=0) > 0]
    if V.shape[1] == 0:
        return None
    gain = np.clip(1.0 - (_distances(segs, V) / thr) ** 2, 0.0, None)
    v = V[:, int(np.argmax(ln @ gain))]
    for _ in range(2):
        ok = _distances(segs, v[:, None])[:, 0] < thr
        if ok.sum() < 2:
            return None
        try:
            v = fit_vanishing_point(segs[ok], width, height).point
        except VebuildError:  # a fit the inliers cannot make (all on one image line): none found
            return None
    ok = _distances(segs, v[:, None])[:, 0] < thr
    if ok.sum() < 2:
        return None
    agree = np.zeros(n, bool)
    agree[order] = ok
    return np.asarray(v, float), agree


def _unit(x: Array) -> Array:
    return np.asarray(x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300), float)


def _distinct(idx: NDArray[np.int64]) -> NDArray[np.int64]:
    """The rows of idx whose entries differ."""
    srt = np.sort(idx, axis=1)
    return idx[np.all(np.diff(srt, axis=1) > 0, axis=1)]


def _hypotheses(rng: np.random.Generator, segs: Array, p: Array, c: Array, fmin: float, fmax: float,
                focal_prior: tuple[float, float] | None, count: int) -> tuple[Array, Array]:
    """Manhattan frames (H, 3, 3) and focal lengths (H,) drawn as the module docstring says."""
    n = len(segs)
    H1 = np.c_[segs[:, :2], np.ones(n)]
    H2 = np.c_[segs[:, 2:], np.ones(n)]
    lines = np.cross(H1, H2)
    # Four segments: f from the orthogonality of their two vanishing points.
    n4 = count // 2
    idx = _distinct(rng.choice(n, (n4, 4), p=p))
    v1 = np.cross(lines[idx[:, 0]], lines[idx[:, 1]])
    v2 = np.cross(lines[idx[:, 2]], lines[idx[:, 3]])
    with np.errstate(divide="ignore", invalid="ignore"):
        a1 = v1[:, :2] / v1[:, 2:3] - c
        a2 = v2[:, :2] / v2[:, 2:3] - c
        f2 = -np.sum(a1 * a2, axis=1)
    ok = np.isfinite(f2) & (f2 > fmin**2) & (f2 < fmax**2)
    fA = np.sqrt(f2[ok])
    d1A = np.c_[a1[ok] / fA[:, None], np.ones(len(fA))]
    d2A = np.c_[a2[ok] / fA[:, None], np.ones(len(fA))]
    # Three segments and a focal length drawn from the prior (or the range).
    n3 = count - n4
    if focal_prior is not None:
        rel = max(focal_prior[1] / focal_prior[0], 0.01)
        half = n3 // 2
        fB = np.r_[focal_prior[0] * np.exp(rng.normal(0.0, rel, half)),
                   np.exp(rng.uniform(np.log(fmin), np.log(fmax), n3 - half))]
    else:
        fB = np.exp(rng.uniform(np.log(fmin), np.log(fmax), n3))
    idx = _distinct(rng.choice(n, (n3, 3), p=p))
    fB = fB[: len(idx)]

    def normal(k: NDArray[np.int64]) -> Array:
        q1 = np.c_[(segs[k, :2] - c) / fB[:, None], np.ones(len(k))]
        q2 = np.c_[(segs[k, 2:] - c) / fB[:, None], np.ones(len(k))]
        return np.cross(q1, q2)

    n0, n1, n2 = normal(idx[:, 0]), normal(idx[:, 1]), normal(idx[:, 2])
    d1B = np.cross(n0, n1)
    d2B = np.cross(d1B, n2)
    d1, d2 = np.r_[d1A, d1B], np.r_[d2A, d2B]
    f = np.r_[fA, fB]
    d1 = _unit(d1)
    d2 = _unit(d2 - d1 * np.sum(d1 * d2, axis=1, keepdims=True))
    d3 = np.cross(d1, d2)
    D = np.stack([d1, d2, d3], axis=2)
    good = np.all(np.isfinite(D), axis=(1, 2)) & (np.linalg.norm(d3, axis=1) > 0.5)
    return D[good], f[good]


def _batch_scores(segs: Array, length: Array, D: Array, f: Array, c: Array, thr: float) -> Array:
    """Truncated-quadratic inlier length of each hypothesis (H,)."""
    V = np.array(D)
    V[:, 0, :] = f[:, None] * D[:, 0, :] + c[0] * D[:, 2, :]
    V[:, 1, :] = f[:, None] * D[:, 1, :] + c[1] * D[:, 2, :]  # K D, (H, 3, 3)
    m = 0.5 * (segs[:, :2] + segs[:, 2:])
    half = 0.5 * (segs[:, 2:] - segs[:, :2])
    l0 = m[None, :, 1:2] * V[:, None, 2, :] - V[:, None, 1, :]  # (H, n, 3)
    l1 = V[:, None, 0, :] - m[None, :, 0:1] * V[:, None, 2, :]
    dist = np.abs(l0 * half[None, :, 0:1] + l1 * half[None, :, 1:2]) / np.maximum(np.hypot(l0, l1), 1e-300)
    best = dist.min(axis=2)
    gain = np.clip(1.0 - (best / thr) ** 2, 0.0, None)
    return np.asarray(gain @ length, float)


def _rot(w: Array) -> Array:
    th = float(np.linalg.norm(w))
    if th < 1e-15:
        return np.eye(3)
    k = w / th
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * Kx + (1 - np.cos(th)) * Kx @ Kx


def _refine(segs: Array, lab: Array, D0: Array, f0: float, c: Array, focal_prior: tuple[float, float] | None,
            fmin: float, fmax: float, sigma: Array | None) -> tuple[Array, float, float]:
    """f and the frame by robust least squares on the labelled segments' end-point distances."""
    use = lab >= 0
    if use.sum() < 3:
        return D0, f0, np.inf
    S, L = segs[use], lab[use]
    w = 1.0 / (sigma[use] if sigma is not None else np.ones(use.sum()))

    def res(x: Array) -> Array:
        f = f0 * np.exp(x[0])
        D = _rot(x[1:4]) @ D0
        K = np.array([[f, 0, c[0]], [0, f, c[1]], [0, 0, 1.0]])
        V = K @ D
        d = _distances(S, V)[np.arange(len(S)), L]
        out = d * w
        if focal_prior is not None:
            out = np.r_[out, (f - focal_prior[0]) / focal_prior[1]]
        return out

    sol = least_squares(res, np.zeros(4), loss="soft_l1", f_scale=3.0, x_scale=np.array([0.05, 0.01, 0.01, 0.01]))
    f = float(np.clip(f0 * np.exp(sol.x[0]), fmin, fmax))
    D = _rot(sol.x[1:4]) @ D0
    J = sol.jac
    try:
        cov = np.linalg.inv(J.T @ J)
        f_sigma = float(np.sqrt(max(cov[0, 0], 0.0))) * f
    except np.linalg.LinAlgError:
        f_sigma = np.inf
    return D, f, f_sigma


def orient_axes(D: Array, x_axis: str = "right") -> tuple[Array, tuple[int, int, int]]:
    """The frame's columns as world x, y, z in camera coordinates (module docstring), and which of
    D's columns each is."""
    if x_axis not in X_AXIS_CHOICES:
        raise ValueError(f"x_axis: expected one of {', '.join(X_AXIS_CHOICES)}, got {x_axis!r}")
    iz = int(np.argmax(np.abs(D[1])))
    z = D[:, iz] * (-1.0 if D[1, iz] > 0 else 1.0)  # image v grows downward: up is −y_cam
    rest = [i for i in range(3) if i != iz]
    if x_axis in ("right", "left"):
        ix = max(rest, key=lambda i: abs(D[0, i]) / max(np.hypot(D[0, i], D[2, i]) + 1e-12, 1e-12))
        x = D[:, ix] * (1.0 if D[0, ix] >= 0 else -1.0)
        if x_axis == "left":
            x = -x
    else:
        ix = max(rest, key=lambda i: abs(D[2, i]))
        x = D[:, ix] * (1.0 if D[2, ix] >= 0 else -1.0)
        if x_axis == "toward":
            x = -x
    iy = [i for i in rest if i != ix][0]
    y = np.cross(z, x)
    return np.column_stack([x, y, z]), (ix, iy, iz)


def direct_segment(seg: Array, d: Array, f: float, c: Array) -> Array:
    """The segment (4,) ordered so that it runs toward the positive end of the camera-frame
    direction d: the image motion of a point moving along +d is d_xy − p d_z (normalised p)."""
    m = 0.5 * (seg[:2] + seg[2:])
    pn = (m - c) / f
    motion = d[:2] - pn * d[2]
    if (seg[2:] - seg[:2]) @ motion < 0:
        return np.r_[seg[2:], seg[:2]]
    return np.asarray(seg, float)


def plumb_line_k1(polylines: Array, sigma_px: Array, f: float, c: Array, width: int, height: int) -> float:
    """The division model's k1 that makes the detected edges straightest (the plumb-line method):
    the robust sum over polylines (n, 2m) of their middle points' squared distances, in units of
    their 1σ, to the line through their end points once undistorted with f, c and k1. A prior for
    grouping only (the calibration estimates k1 itself); 0 where the edges do not say."""
    from scipy.optimize import minimize_scalar

    if len(polylines) < 4:
        return 0.0
    P = polylines.reshape(len(polylines), -1, 2)
    length = np.linalg.norm(P[:, -1] - P[:, 0], axis=1)
    keep = length >= 0.1 * max(width, height)
    if keep.sum() < 4:
        return 0.0
    P, s = P[keep], sigma_px[keep]
    r_max2 = float(np.max(np.sum(((np.array([[0, 0], [width, height]]) - c) / f) ** 2, axis=1)))

    def cost(k1: float) -> float:
        x = (P - c) / f
        u = x / (1.0 + k1 * np.sum(x**2, axis=2, keepdims=True))
        a, b = u[:, :1], u[:, -1:]
        d = b - a
        n = np.stack([-d[..., 1], d[..., 0]], axis=-1) / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
        off = np.sum((u[:, 1:-1] - a) * n, axis=-1) * f / s[:, None]
        return float(np.sum(np.log1p(off**2 / 9.0)))  # Cauchy: edges that are truly curved do not pull

    bound = 0.25 / r_max2  # at most 25 % of the corner's radius either way
    best = minimize_scalar(cost, bounds=(-bound, bound), method="bounded", options={"xatol": 1e-4 / r_max2})
    k1 = float(best.x)
    return k1 if cost(k1) < cost(0.0) - 4.0 else 0.0
