"""What a careful user would click: directed vanishing segments and marker observations."""

from __future__ import annotations

import math

import numpy as np

from .cameras import distort_normalised, project
from .parameters import (
    BASE_WIDTH,
    CLICK_SIGMA_PX,
    EDGE_SAMPLES,
    IMAGE_MARGIN_PX,
    POLYLINE_POINTS,
    POLYLINE_STEP_PX,
    SEGMENT_MIN_PX,
)
from .raycast import visible


def longest_visible_run(scene, cam, p, q, margin):
    """The longest run of consecutive visible samples along segment p → q, as 3D end points."""
    a = np.linspace(0.0, 1.0, EDGE_SAMPLES)
    X = p + a[:, None] * (q - p)
    vis = visible(scene, cam, X, margin)
    best, start, best_run = 0, None, None
    for k, ok in enumerate(np.append(vis, False)):
        if ok and start is None:
            start = k
        elif not ok and start is not None:
            if k - start > best:
                best, best_run = k - start, (start, k - 1)
            start = None
    if best_run is None or best < 2:
        return None
    return X[best_run[0]], X[best_run[1]]


def _line_distance(p, a, b):
    """Distance of image point p from the infinite line through a, b."""
    d = b - a
    return abs(d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0])) / np.linalg.norm(d)


def _bow(cam: dict, X1: np.ndarray, X2: np.ndarray) -> float:
    """How far the lens bends the image of the straight run X1 → X2: the largest distance of its
    image from the chord of its ends (px; 0 through a pinhole)."""
    if cam.get("k1", 0.0) == 0.0:
        return 0.0
    a = np.linspace(0.0, 1.0, 33)[:, None]
    uv, _ = project(cam, X1 + a * (X2 - X1))
    return max(_line_distance(p, uv[0], uv[-1]) for p in uv)


def choose_segments(scene: dict, cam: dict, axis: str, n_max: int = 6, n_min: int = 4) -> list[dict]:
    """Pick up to n_max long, well-spread visible runs of the scene's edges along axis.

    Longest first (through a lens that bends lines, the most bent first: _bow); a run is skipped
    when it lies on nearly the same image line as one already taken, or (in the first pass) when
    its midpoint crowds one already taken.
    """
    scale = cam["width"] / BASE_WIDTH
    margin, min_len = IMAGE_MARGIN_PX * scale, SEGMENT_MIN_PX * scale
    cands = []
    for name, p, q in scene["edges"][axis]:
        run = longest_visible_run(scene, cam, p, q, margin)
        if run is None:
            continue
        uv, _ = project(cam, np.array(run))
        length = float(np.linalg.norm(uv[1] - uv[0]))
        if length >= min_len:
            cands.append({"edge": name, "X1": run[0], "X2": run[1], "uv": uv, "length": length,
                          "bow": _bow(cam, run[0], run[1])})
    # Through a pinhole, the longest first. Through a lens that bends lines, a careful user marks
    # the edges it bends most first (long ones far from the centre: they tell the lens apart).
    cands.sort(key=lambda c: -c["bow"] if cam.get("k1", 0.0) != 0.0 else -c["length"])
    spread = 0.12 * math.hypot(cam["width"], cam["height"])
    same_line = 20.0 * scale
    chosen: list[dict] = []
    for crowd in (spread, 0.0):
        for c in cands:
            if len(chosen) >= n_max:
                break
            if any(c is o for o in chosen):
                continue
            mid = c["uv"].mean(axis=0)
            dup = any(max(_line_distance(c["uv"][0], *o["uv"]), _line_distance(c["uv"][1], *o["uv"]))
                      < same_line for o in chosen)
            crowded = any(np.linalg.norm(mid - o["uv"].mean(axis=0)) < crowd for o in chosen)
            if not dup and not crowded:
                chosen.append(c)
        if len(chosen) >= n_min:
            break
    return chosen


def polyline_points(cam: dict, X1: np.ndarray, X2: np.ndarray, length: float) -> np.ndarray:
    """Where a careful user clicks along the image of the straight edge X1 → X2 on a photo whose
    lens bends it: n points (POLYLINE_POINTS, one more per POLYLINE_STEP_PX of the run's image
    length), evenly spaced along the edge's image as a pinhole would show it (a straight line
    there), then put where the lens shows them. Returns (n, 2), first → last along +axis."""
    lo, hi = POLYLINE_POINTS
    n = int(min(hi, max(lo, 2 + math.ceil(length / (POLYLINE_STEP_PX * cam["width"] / BASE_WIDTH)))))
    pin, _ = project(cam, np.array([X1, X2]), lens=False)
    a = np.linspace(0.0, 1.0, n)[:, None]
    line = pin[0] + a * (pin[1] - pin[0])
    K = cam["K"]
    f = np.array([K[0, 0], K[1, 1]])
    return distort_normalised((line - K[:2, 2]) / f, cam["k1"]) * f + K[:2, 2]


def annotate(scene: dict, cam: dict, rng: np.random.Generator) -> dict:
    """The clicks of a careful user on this photo, with N(0, 0.7 px · scale) noise per coordinate.

    Returns {"vanishing_segments": axis → [[u1, v1, u2, v2], ...] (directed along +axis),
    "segments_truth": axis → [{"edge", "X1", "X2"}] (the 3D run each segment was clicked on),
    "marker_observations": name → [u, v]}. On a photo through a distorting lens (cameras.LENS_K1)
    every segment is a polyline [u1, v1, …, un, vn] of 3–5 points along the bent image of its edge
    (polyline_points), the middle ones carrying its curvature; all clicks are where the lens put
    the points.
    """
    sigma = CLICK_SIGMA_PX * cam["width"] / BASE_WIDTH
    segs, truth = {}, {}
    for axis in "xyz":
        chosen = choose_segments(scene, cam, axis)
        if not chosen:
            continue
        if cam.get("k1", 0.0) == 0.0:
            uv = np.array([c["uv"].reshape(4) for c in chosen])  # X1 → X2 is the +axis sense
            segs[axis] = uv + rng.normal(0.0, sigma, uv.shape)
        else:
            pts = [polyline_points(cam, c["X1"], c["X2"], c["length"]).reshape(-1) for c in chosen]
            segs[axis] = [p + rng.normal(0.0, sigma, p.shape) for p in pts]
        truth[axis] = [{"edge": c["edge"], "X1": c["X1"], "X2": c["X2"]} for c in chosen]
    names = list(scene["markers"])
    P = np.array([scene["markers"][n][0] for n in names])
    vis = visible(scene, cam, P, IMAGE_MARGIN_PX * cam["width"] / BASE_WIDTH)
    uv, _ = project(cam, P)
    uv = uv + rng.normal(0.0, sigma, uv.shape)  # drawn for every marker: stable streams
    obs = {n: uv[k] for k, n in enumerate(names) if vis[k]}
    return {"vanishing_segments": segs, "segments_truth": truth, "marker_observations": obs}
