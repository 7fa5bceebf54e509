"""How often the x-axis choice from shared markers is right, undecided or wrong: ``vebuild bench orient``.

Generated pairs of photos of a building (3072 × 2048, f 0.7–1.3 × the width; the markers on the
façades, 4–30 m away, inside both images), each photo's rotation known from its vanishing points
only to the noise of real ones (:data:`ROTATION_SIGMAS_DEG` per axis, each in turn) and its focal length to
:data:`FOCAL_SIGMA_REL`, the markers clicked with :data:`CLICK_SIGMA_PX` noise. The second photo's
axes are turned by a random k·90° about z, and :func:`vebuild.calibration.axes_choice.choose_turns`
is asked for k from the first, with ``n`` shared markers (2…8) and the rule's thresholds as they
stand, for three view geometries: the angle between the two views at the scene of 5–20° (small),
20–60° (medium) and 60–120° (wide). The figures say, per n and geometry, the share of pairs
decided right, left undecided and decided wrong: the rule must (near) never decide wrong, and
:data:`vebuild.calibration.axes_choice.MIN_SHARED_MARKERS` is the smallest n at which it decides
at all.
"""

from __future__ import annotations

import numpy as np

from vebuild.calibration.axes_choice import MIN_SHARED_MARKERS, choose_turns, rz
from vebuild.console.bars import Bar

Array = np.ndarray

WIDTH, HEIGHT = 3072, 2048
#: 1σ of one click (pixels).
CLICK_SIGMA_PX = 1.0
#: 1σ per axis of a photo's rotation from its vanishing points (degrees): detected points on real
#: façades are good to 0.1–0.3° (docs/detect.md); 1° is a photo whose lines include clutter.
ROTATION_SIGMAS_DEG = (0.3, 1.0)
ROTATION_SIGMA_DEG = ROTATION_SIGMAS_DEG[0]  # the one :func:`one_pair` draws with
#: 1σ of the focal length from the vanishing points (relative).
FOCAL_SIGMA_REL = 0.02
GEOMETRIES = {"small": (5.0, 20.0), "medium": (20.0, 60.0), "wide": (60.0, 120.0)}
SHARED = (2, 3, 4, 5, 6, 8)


def _look(C: Array, target: Array, roll_deg: float) -> Array:
    """World→camera rotation of a camera at C looking at target (image v down), rolled."""
    fwd = target - C
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    R = np.vstack([right, down, fwd])
    a = np.radians(roll_deg)
    Rr = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return Rr @ R


def _small_rotation(rng: np.random.Generator, sigma_deg: float) -> Array:
    w = np.radians(rng.normal(0.0, sigma_deg, 3))
    th = float(np.linalg.norm(w))
    if th == 0.0:
        return np.eye(3)
    k = w / th
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * Kx + (1 - np.cos(th)) * Kx @ Kx


def one_pair(rng: np.random.Generator, n: int, geometry: str) -> tuple[str, float, float] | None:
    """One pair: 'right', 'undecided' or 'wrong', with the best and second-best RMS miss (°); None
    where no pair of cameras seeing n markers was drawn."""
    lo, hi = GEOMETRIES[geometry]
    for _ in range(200):
        centre = np.array([0.0, 0.0, rng.uniform(2.0, 6.0)])
        # Markers on two façades meeting at a corner (x = 0 and y = 0 planes), up to 12 m along them.
        pts = []
        for _m in range(n):
            along, up = rng.uniform(0.5, 12.0), rng.uniform(0.0, 10.0)
            pts.append([along, 0.0, up] if rng.random() < 0.5 else [0.0, along, up])
        X = np.array(pts)
        centre = np.r_[X[:, :2].mean(axis=0), X[:, 2].mean()]
        dist = rng.uniform(8.0, 30.0, 2)
        az0 = rng.uniform(np.radians(15), np.radians(75))  # in the open quadrant, facing the corner
        sep = np.radians(rng.uniform(lo, hi)) * rng.choice([-1.0, 1.0])
        az = [az0, az0 + sep]
        cams = []
        for d, a in zip(dist, az, strict=True):
            C = centre + d * np.array([np.cos(a), np.sin(a), 0.0])
            C[2] = rng.uniform(1.4, 1.8)
            f = WIDTH * rng.uniform(0.7, 1.3)
            R = _look(C, centre + rng.normal(0.0, 1.0, 3), rng.normal(0.0, 2.0))
            xc = (X - C) @ R.T
            if np.any(xc[:, 2] < 1.0):
                break
            uv = f * xc[:, :2] / xc[:, 2:] + [WIDTH / 2, HEIGHT / 2]
            if np.any(uv < 5) or np.any(uv[:, 0] > WIDTH - 5) or np.any(uv[:, 1] > HEIGHT - 5):
                break
            cams.append((R, f, uv))
        if len(cams) < 2:
            continue
        rays, rots = {}, {}
        k_true = int(rng.integers(4))
        for name, (R, f, uv), k in zip("ab", cams, (0, k_true), strict=True):
            f_est = f * (1.0 + rng.normal(0.0, FOCAL_SIGMA_REL))
            clicks = uv + rng.normal(0.0, CLICK_SIGMA_PX, uv.shape)
            xy = (clicks - [WIDTH / 2, HEIGHT / 2]) / f_est
            rays[name] = {f"m{i}": np.array([x, y, 1.0]) for i, (x, y) in enumerate(xy)}
            R_est = _small_rotation(rng, ROTATION_SIGMA_DEG) @ R
            rots[name] = R_est @ rz(-k)  # its k = 0 candidate: the truth turned back by k
        d = choose_turns(rots, rays, {"a": 0}, min_shared=2)["b"]  # the thresholds alone, at every n
        res = sorted(d.residual_deg) if d.residual_deg else [np.nan, np.nan]
        if d.turn is None:
            return "undecided", res[0], res[1]
        return ("right" if d.turn == k_true else "wrong"), res[0], res[1]
    return None


def run(quick: bool = False, progress: bool = True) -> dict[str, float]:
    """Per rotation noise, view geometry and shared-marker count n: the shares right / undecided /
    wrong (keys ``rot{σ}_{geometry}_n{n}_{right|undecided|wrong}_share``)."""
    global ROTATION_SIGMA_DEG
    pairs = 100 if quick else 1000
    rng = np.random.default_rng(20261207)
    out: dict[str, float] = {"pairs_per_cell": float(pairs), "min_shared_markers": float(MIN_SHARED_MARKERS)}
    kept = ROTATION_SIGMA_DEG
    try:
        for rot in Bar(ROTATION_SIGMAS_DEG, desc="bench orient", unit="noise level", disable=not progress):
            ROTATION_SIGMA_DEG = rot
            for geometry in GEOMETRIES:
                for n in SHARED:
                    counts = {"right": 0, "undecided": 0, "wrong": 0}
                    done = 0
                    while done < pairs:
                        r = one_pair(rng, n, geometry)
                        if r is None:
                            continue
                        counts[r[0]] += 1
                        done += 1
                    for k, v in counts.items():
                        out[f"rot{rot:g}_{geometry}_n{n}_{k}_share"] = v / pairs
    finally:
        ROTATION_SIGMA_DEG = kept
    return out


def table(figures: dict[str, float]) -> str:
    lines = [f"x-axis choice from shared markers: {int(figures['pairs_per_cell'])} generated pairs per cell "
             f"(right / undecided / wrong); the rule asks for {int(figures['min_shared_markers'])} shared markers"]
    for rot in ROTATION_SIGMAS_DEG:
        lines += ["", f"rotations off {rot:g}° per axis (1σ)",
                  " " * 31 + "  ".join(f"{'n=' + str(n):>17}" for n in SHARED)]
        for g in GEOMETRIES:
            cells = []
            for n in SHARED:
                r, u, w = (figures.get(f"rot{rot:g}_{g}_n{n}_{k}_share", float("nan"))
                           for k in ("right", "undecided", "wrong"))
                cells.append(f"{r:5.3f}/{u:5.3f}/{w:5.3f}")
            lines.append(f"  {g:<28} " + "  ".join(f"{c:>17}" for c in cells))
    return "\n".join(lines)
