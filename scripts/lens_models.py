"""Which lens model straightens a CCTV lens: fit each candidate to a true fisheye's mapping.

For equidistant (r = f θ) and equisolid (r = 2 f sin(θ/2)) lenses whose diagonal field of view
is 90°, 120° or 150°, on 1280×720 and 704×576 frames, fit (a) the one-term division model,
(b) the two-term division model x_u = x_d / (1 + k1 r_d² + k2 r_d⁴), (c) Kannala–Brandt
θ_d = θ (1 + k1 θ² + k2 θ⁴) (focal length free in each) by least squares over a grid of the
frame's pixels, and print the worst pixel error over the frame. Run: python3 scripts/lens_models.py
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares


def true_radius(theta: np.ndarray, f: float, kind: str) -> np.ndarray:
    return f * theta if kind == "equidistant" else 2.0 * f * np.sin(theta / 2.0)


def division_distorted(r_u: np.ndarray, k1: float, k2: float, r_hi: float) -> np.ndarray:
    """r_d with r_d / (1 + k1 r_d² + k2 r_d⁴) = r_u, by bisection on [0, r_hi] (monotone there)."""
    lo, hi = np.zeros_like(r_u), np.full_like(r_u, r_hi)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        g = mid / (1.0 + k1 * mid**2 + k2 * mid**4)
        below = g < r_u
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def fit(kind: str, fov_deg: float, w: int, h: int) -> dict[str, float]:
    half_diag = 0.5 * np.hypot(w, h)
    half = np.radians(fov_deg) / 2.0
    f = half_diag / half if kind == "equidistant" else half_diag / (2.0 * np.sin(half / 2.0))
    u, v = np.meshgrid(np.linspace(0, w, 97), np.linspace(0, h, 73))
    r = np.hypot(u - w / 2, v - h / 2).ravel()
    theta = r / f if kind == "equidistant" else 2.0 * np.arcsin(np.clip(r / (2.0 * f), -1, 1))
    r_true = true_radius(theta, f, kind)
    t_u = np.tan(theta)  # the pinhole's normalised radius
    out = {}

    def division(p: np.ndarray, two: bool) -> np.ndarray:
        fm, k1 = p[0], p[1]
        k2 = p[2] if two else 0.0
        # the mapping's rim: where r_d/(1+k1 r²+k2 r⁴) stops increasing; search r_hi up to it
        rr = np.linspace(1e-6, 3.0 * half_diag / fm, 4000)
        g = rr / (1 + k1 * rr**2 + k2 * rr**4)
        stop = np.nonzero(np.diff(g) <= 0)[0]
        r_hi = rr[stop[0]] if len(stop) else rr[-1]
        return fm * division_distorted(t_u, k1, k2, r_hi) - r_true

    for name, two in (("division-1", False), ("division-2", True)):
        p0 = [f, -0.1] + ([0.0] if two else [])
        best = least_squares(division, p0, args=(two,), x_scale="jac")
        out[name] = float(np.max(np.abs(division(best.x, two))))

    def kb(p: np.ndarray) -> np.ndarray:
        fm, k1, k2 = p
        return fm * theta * (1 + k1 * theta**2 + k2 * theta**4) - r_true

    best = least_squares(kb, [f, 0.0, 0.0], x_scale="jac")
    out["kannala-brandt"] = float(np.max(np.abs(kb(best.x))))
    return out


def main() -> None:
    print(f"{'lens':12} {'diag':>5} {'frame':>9} {'division-1':>11} {'division-2':>11} {'KB':>9}   (worst px)")
    for kind in ("equidistant", "equisolid"):
        for fov in (90, 120, 150):
            for w, h in ((1280, 720), (704, 576)):
                e = fit(kind, fov, w, h)
                print(f"{kind:12} {fov:4}° {w:4}×{h:<4} {e['division-1']:11.2f} {e['division-2']:11.2f} "
                      f"{e['kannala-brandt']:9.3f}")


if __name__ == "__main__":
    main()
