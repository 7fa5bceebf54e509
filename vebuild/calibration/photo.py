"""Calibrate one photo's intrinsics and rotation from its vanishing segments (paper §2).

The paper fits each vanishing point alone, then reads K and R off them. vebuild starts there
(:mod:`.vanishing`, :mod:`.intrinsics`) and then refines f, the principal point c and R jointly,
with every segment's residual measured against the vanishing point K R eᵢ that the camera
predicts. That single solve:

- keeps the three vanishing points consistent (orthogonal directions) instead of fitting each
  alone;
- treats a vanishing point at infinity like any other (it is just K R eᵢ with zero third row);
- adds a prior pulling c toward the image centre (or a given point) with a stated 1σ, so that
  the orthocentre's notorious instability cannot drag c tens of pixels away, while three good
  vanishing points still override it (maximum a posteriori rather than either pure mode);
- yields the covariance of (f, cx, cy, ω) from its Jacobian.

The *mode* says what determined the intrinsics, judged from the information the segments alone
carry: ``3vp`` (f and c), ``2vp`` (f; c from its prior), ``1vp`` (f from EXIF or the user).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from ..camera import AXES, exp_so3, intrinsic_matrix, ypr_from_rotation
from ..determinism import deterministic
from ..errors import CalibrationError
from .intrinsics import focal_squared, orthocentre, rotation_from_vanishing_points
from .lsq import covariance_from_jacobian, numeric_jacobian, photo_numeric_failures, variance_factor
from .priors import DistortionPrior, FocalPrior  # noqa: F401 -- re-exported
from .vanishing import check_segments, fit_vanishing_point, normalising_transform, segment_residuals

Array = NDArray[np.float64]

#: The segments determine f when their own 1σ on f is at most this fraction of f; otherwise the
#: focal length must come from EXIF or the user ('1vp' mode).
FOCAL_FROM_SEGMENTS_MAX_REL_SIGMA = 0.05
#: Two axes whose vanishing points are closer than this (degrees, seen from a nominal camera with
#: f = the image's longer side) are the same direction: the user has mislabelled a set.
SAME_VANISHING_POINT_DEG = 3.0
#: A vanishing point farther than this many half-image-sizes from the centre is treated as at
#: infinity when choosing the closed-form start (the joint solve itself needs no such cut).
FINITE_VP_MAX_RADIUS = 30.0
#: Variance of a segment residual for isotropic click noise σ on each end point: the distance of
#: an end point to the line through the midpoint is ½(n₁ − n₂)⊥, so its variance is σ²/2.
SEGMENT_RESIDUAL_VARIANCE_FACTOR = 0.5


@dataclass(frozen=True)
class PhotoCalibration:
    """Intrinsics and rotation of one photo with their uncertainty.

    covariance : (6, 6) over (f, cx, cy, ωx, ωy, ωz), pixels and radians, where ω is a small
        rotation on the camera side: R_true = exp([ω]×) R.
    """

    photo: str
    width: int
    height: int
    mode: str
    mode_reason: str
    focal_source: str
    K: Array
    R: Array
    covariance: Array
    vanishing_points: dict[str, Array]
    segment_residuals_px: dict[str, Array]

    @property
    def f(self) -> float:
        return float(self.K[0, 0])

    @property
    def principal_point(self) -> Array:
        return self.K[:2, 2].copy()

    @property
    def f_sigma(self) -> float:
        return float(np.sqrt(self.covariance[0, 0]))

    @property
    def principal_point_sigma(self) -> Array:
        return np.sqrt(np.diag(self.covariance)[1:3])

    @property
    def rotation_sigma_rad(self) -> Array:
        """1σ of the small rotation ω about the camera's x, y, z axes."""
        return np.sqrt(np.diag(self.covariance)[3:6])

    def ypr(self) -> tuple[Array, Array]:
        """(yaw, pitch, roll) in radians and their 1σ."""
        return ypr_with_sigma(self.R, self.covariance[3:6, 3:6])

    @property
    def rms_px(self) -> float:
        r = np.concatenate(list(self.segment_residuals_px.values()))
        return float(np.sqrt(np.mean(r**2)))


def ypr_with_sigma(R: Array, cov_omega: Array) -> tuple[Array, Array]:
    """Yaw, pitch, roll of R and their 1σ propagated from the covariance of ω (R = exp(ω) R̂)."""
    ypr0 = ypr_from_rotation(R)

    def f(w: Array) -> Array:
        d = ypr_from_rotation(exp_so3(w) @ R) - ypr0
        return (d + np.pi) % (2 * np.pi) - np.pi

    J = numeric_jacobian(f, np.zeros(3), 1e-7)
    return ypr0, np.sqrt(np.maximum(np.diag(J @ cov_omega @ J.T), 0.0))


@deterministic
@photo_numeric_failures("its calibration from the vanishing lines", "check its vanishing segments (each along "
                        "its axis and in its direction, not all parallel, of some length)")
def calibrate_photo(
    segments: Mapping[str, ArrayLike],
    width: int,
    height: int,
    *,
    photo: str = "photo",
    click_sigma_px: float = 1.0,
    principal_point: tuple[ArrayLike, float] | None = None,
    principal_point_sigma_rel: float = 0.01,
    focal: FocalPrior | None = None,
    exif_focal: FocalPrior | None = None,
) -> PhotoCalibration:
    """Intrinsics and rotation of one photo from its directed vanishing segments.

    Parameters
    ----------
    segments : axis ('x', 'y', 'z') → (n, 4) directed segments u1, v1, u2, v2 (pixels); axes
        with no segments may be absent or empty.
    width, height : image size in pixels.
    photo : name used in error messages.
    click_sigma_px : 1σ of one clicked end point.
    principal_point : a known principal point and its 1σ (pixels); default the image centre
        with 1σ = principal_point_sigma_rel × the longer side.
    focal : a focal length the user gives (always used as a prior).
    exif_focal : the focal length EXIF records; used where it is more certain than what the
        segments say about f, and needed where they say nothing.

    Raises
    ------
    CalibrationError : when the marks cannot determine the camera; the message says why.
    """
    for name, prior in (("focal_px", focal), ("the EXIF focal length", exif_focal)):
        if prior is not None and not (np.isfinite(prior.value) and prior.value > 0 and np.isfinite(prior.sigma)
                                      and prior.sigma > 0):
            raise CalibrationError(photo, f"{name}: expected a focal length > 0 px with a σ > 0 px, got "
                                   f"{prior.value!r} ± {prior.sigma!r}")
    if principal_point is not None and not (np.all(np.isfinite(np.asarray(principal_point[0], float)))
                                            and np.isfinite(principal_point[1]) and principal_point[1] > 0):
        raise CalibrationError(photo, f"principal_point: expected a finite (u, v) with a σ > 0 px, got "
                               f"{principal_point[0]!r} ± {principal_point[1]!r}")
    segs = {a: check_segments(s, a, photo) for a, s in segments.items() if len(np.asarray(s).reshape(-1)) > 0}
    if len(segs) < 2:
        marked = ", ".join(sorted(segs)) or "none"
        raise CalibrationError(
            photo,
            f"vanishing segments are marked on {len(segs)} axis ({marked}); the rotation needs two "
            "axes at least: mark a second direction, such as the horizon (x or y) or verticals (z)",
        )
    axes = [a for a in AXES if a in segs]
    fits = {a: fit_vanishing_point(segs[a], width, height, axis=a, photo=photo) for a in axes}
    N = normalising_transform(width, height)
    unit = {}
    for a in axes:
        x = N @ fits[a].point
        unit[a] = x / np.linalg.norm(x)
    for a, b in combinations(axes, 2):
        # Points on the sphere up to sign: the angle between the two lines through the origin.
        ang = np.degrees(np.arccos(min(1.0, abs(float(unit[a] @ unit[b])))))
        if ang < SAME_VANISHING_POINT_DEG:
            raise CalibrationError(
                photo,
                f"the segments of axes {a} and {b} meet at the same vanishing point ({ang:.1f}° apart); "
                "orthogonal directions cannot: one of the two sets is labelled with the wrong axis",
            )

    c0 = np.array([width / 2.0, height / 2.0])
    sigma_c = principal_point_sigma_rel * max(width, height)
    if principal_point is not None:
        c0 = np.asarray(principal_point[0], float)
        sigma_c = float(principal_point[1])

    finite = [a for a in axes if abs(unit[a][2]) > 1.0 / FINITE_VP_MAX_RADIUS]
    f0, c_init = _closed_form_start(fits, finite, c0, photo, focal or exif_focal)
    K0 = intrinsic_matrix(f0, *c_init)
    R0, handedness = rotation_from_vanishing_points(K0, {a: fits[a].point for a in axes}, segs)
    if handedness < 0:
        raise CalibrationError(
            photo,
            "the directions of the x, y and z segments form a left-handed frame; each segment must "
            "run toward the positive end of its axis: one set is drawn backwards",
        )

    weight = 1.0 / (click_sigma_px * np.sqrt(SEGMENT_RESIDUAL_VARIANCE_FACTOR))
    scale = max(width, height)
    problem = _Problem(segs, axes, weight, scale, c0, sigma_c)
    # A focal length the user gives is always used. EXIF is used where it says more about f than
    # the segments do (judged after a solve), and from the start where the segments cannot give f.
    prior_f = focal if focal is not None else (exif_focal if len(finite) < 2 else None)
    x, R = problem.solve(f0, c_init, R0, prior_f)
    sigma_f_data, sigma_c_data = problem.data_information(x, R)
    rel = sigma_f_data / (x[0] * scale)
    if focal is None and exif_focal is not None:
        wanted = exif_focal if rel > exif_focal.sigma / exif_focal.value else None
        if wanted is not prior_f:
            prior_f = wanted
            x, R = problem.solve(x[0] * scale, x[1:3] * scale, R, prior_f)
    if prior_f is None:
        focal_source = "vanishing points"
    elif rel > FOCAL_FROM_SEGMENTS_MAX_REL_SIGMA:
        focal_source = prior_f.source
    else:
        focal_source = f"vanishing points + {prior_f.source}"
    if prior_f is None and rel > FOCAL_FROM_SEGMENTS_MAX_REL_SIGMA:
        raise CalibrationError(
            photo,
            f"the focal length is not determined: from these segments its 1σ would be {100 * rel:.1f} %, "
            f"more than the {100 * FOCAL_FROM_SEGMENTS_MAX_REL_SIGMA:g} % that determines it "
            "(the vanishing points lie near infinity or too close to the image centre); mark edges "
            "along a third axis that recedes from the camera, or give the focal length (the photo "
            "has no EXIF focal length)",
        )

    if rel > FOCAL_FROM_SEGMENTS_MAX_REL_SIGMA:
        mode = "1vp"
        reason = (
            f"the segments alone fix f only to {100 * min(rel, 9.99):.0f} %, so f comes from "
            f"{focal_source}; the principal point from its prior"
        )
    elif sigma_c_data <= sigma_c:
        mode = "3vp"
        reason = (
            f"three vanishing points fix f (1σ {100 * rel:.2f} % from the segments) and the principal "
            f"point (1σ {sigma_c_data:.0f} px from the segments, prior {sigma_c:.0f} px)"
        )
    else:
        mode = "2vp"
        why = "a third axis is not marked" if len(axes) == 2 else "the third vanishing point is near infinity"
        reason = (
            f"two vanishing points fix f (1σ {100 * rel:.2f} % from the segments); {why}, so the "
            "principal point comes from its prior"
        )

    J = problem.jacobian(x, R, prior_f)
    r = problem.residuals(np.r_[x[:3], 0.0, 0.0, 0.0], R, prior_f)
    cov_scaled = covariance_from_jacobian(J) * variance_factor(r, 6)
    S = np.diag([scale, scale, scale, 1.0, 1.0, 1.0])
    K = intrinsic_matrix(*(x[:3] * scale))
    return PhotoCalibration(
        photo=photo,
        width=int(width),
        height=int(height),
        mode=mode,
        mode_reason=reason,
        focal_source=focal_source,
        K=K,
        R=R,
        covariance=S @ cov_scaled @ S,
        vanishing_points={a: K @ R[:, "xyz".index(a)] for a in axes},
        segment_residuals_px={a: segment_residuals(K @ R[:, "xyz".index(a)], segs[a]) for a in axes},
    )


@deterministic
def closed_form_calibration(
    segments: Mapping[str, ArrayLike], width: int, height: int, *, photo: str = "photo",
    focal: FocalPrior | None = None,
) -> tuple[Array, Array]:
    """The paper's method alone (§2): per-axis vanishing points, then K and R in closed form.

    Principal point at the orthocentre when three vanishing points are finite, else at the image
    centre; f from two finite vanishing points, else the given focal length. No prior, no joint
    refinement, no uncertainty: the reference that ``vebuild bench calibration`` compares with.
    """
    segs = {a: check_segments(s, a, photo) for a, s in segments.items() if len(np.asarray(s).reshape(-1)) > 0}
    axes = [a for a in AXES if a in segs]
    fits = {a: fit_vanishing_point(segs[a], width, height, axis=a, photo=photo) for a in axes}
    N = normalising_transform(width, height)
    finite = [a for a in axes if abs((N @ fits[a].point)[2]) / np.linalg.norm(N @ fits[a].point)
              > 1.0 / FINITE_VP_MAX_RADIUS]
    f, c = _closed_form_start(fits, finite, np.array([width / 2.0, height / 2.0]), photo, focal)
    K = intrinsic_matrix(f, *c)
    R, _ = rotation_from_vanishing_points(K, {a: fits[a].point for a in axes}, segs)
    return K, R


def _closed_form_start(
    fits: Mapping, finite: list[str], c0: Array, photo: str, prior: FocalPrior | None
) -> tuple[float, Array]:
    """Focal length and principal point to start from (paper §2 closed forms)."""
    pts = {a: fits[a].finite_point() for a in finite}
    if len(finite) == 3:
        c = orthocentre(pts["x"], pts["y"], pts["z"])
        f2 = focal_squared(pts["x"], pts["y"], c)
        if f2 > 0 and np.linalg.norm(c - c0) < np.linalg.norm(c0):  # inside the image's circumcircle
            return float(np.sqrt(f2)), c
    bad = []
    for a, b in combinations(finite, 2):
        f2 = focal_squared(pts[a], pts[b], c0)
        if f2 > 0:
            return float(np.sqrt(f2)), c0
        bad.append((a, b, f2))
    if prior is not None:
        return prior.value, c0
    if bad:
        a, b, f2 = bad[0]
        raise CalibrationError(
            photo,
            f"the vanishing points of axes {a} and {b} give f² = {f2:.4g} px² ≤ 0: for orthogonal "
            "directions they must lie on opposite sides of the principal point; a segment set is "
            "probably labelled with the wrong axis",
        )
    raise CalibrationError(
        photo,
        "fewer than two vanishing points are finite, so the segments cannot give the focal length; "
        "give the focal length or use a photo with EXIF, or mark edges that recede from the camera",
    )


class _Problem:
    """The joint least-squares problem over x = (f/s, cx/s, cy/s, ω), R = exp([ω]×) R̂."""

    def __init__(self, segs: dict, axes: list[str], weight: float, scale: float, c0: Array, sigma_c: float):
        self.segs, self.axes, self.weight, self.scale = segs, axes, weight, scale
        self.c0, self.sigma_c = c0, sigma_c
        self.n_data = sum(len(segs[a]) for a in axes)

    def residuals(self, x: Array, R0: Array, prior_f: FocalPrior | None) -> Array:
        f, cx, cy = x[:3] * self.scale
        K = intrinsic_matrix(f, cx, cy)
        R = exp_so3(x[3:6]) @ R0
        parts = [segment_residuals(K @ R[:, "xyz".index(a)], self.segs[a]) * self.weight for a in self.axes]
        parts.append((np.array([cx, cy]) - self.c0) / self.sigma_c)
        if prior_f is not None:
            parts.append(np.array([(f - prior_f.value) / prior_f.sigma]))
        return np.concatenate(parts)

    def solve(self, f0: float, c: Array, R0: Array, prior_f: FocalPrior | None) -> tuple[Array, Array]:
        x0 = np.r_[f0 / self.scale, np.asarray(c) / self.scale, 0.0, 0.0, 0.0]
        lower = np.r_[1e-3, -np.inf, -np.inf, -np.pi, -np.pi, -np.pi]
        upper = np.r_[1e3, np.inf, np.inf, np.pi, np.pi, np.pi]
        sol = least_squares(
            self.residuals, x0, args=(R0, prior_f), bounds=(lower, upper), method="trf", x_scale="jac",
            xtol=1e-12, ftol=1e-12, gtol=1e-12,
        )
        R = exp_so3(sol.x[3:6]) @ R0
        return np.r_[sol.x[:3], 0.0, 0.0, 0.0], R

    def jacobian(self, x: Array, R: Array, prior_f: FocalPrior | None) -> Array:
        return numeric_jacobian(lambda y: self.residuals(y, R, prior_f), np.r_[x[:3], 0.0, 0.0, 0.0], 1e-7)

    def data_information(self, x: Array, R: Array) -> tuple[float, float]:
        """1σ of f and of c (largest axis) that the segments alone would give, pixels (inf if none)."""
        J = self.jacobian(x, R, None)[: self.n_data]
        info = J.T @ J
        sigma_f = _marginal_sigma(info, [0, 3, 4, 5], 0) * self.scale
        cov = _safe_inverse(info)
        if cov is None:
            sigma_c = np.inf
        else:
            sigma_c = float(np.sqrt(max(np.linalg.eigvalsh(cov[1:3, 1:3]).max(), 0.0))) * self.scale
        return sigma_f, sigma_c


def _safe_inverse(info: Array) -> Array | None:
    w = np.linalg.eigvalsh(info)
    if w.min() <= 1e-12 * max(w.max(), 1e-300):
        return None
    return np.asarray(np.linalg.inv(info), float)


def _marginal_sigma(info: Array, keep: list[int], which: int) -> float:
    cov = _safe_inverse(info[np.ix_(keep, keep)])
    if cov is None:
        return np.inf
    return float(np.sqrt(cov[keep.index(which), keep.index(which)]))
