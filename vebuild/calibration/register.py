"""Register a further photo to known 3D points (paper §3.2).

Two ways, chosen by what the photo offers:

- with vanishing segments: intrinsics and rotation from them (:func:`calibrate_photo`), then the
  camera centre from ≥ 2 points of known position (the lines back from the points along their
  rays meet at the camera), refined over all points;
- without usable vanishing points: from ≥ 4 points of known position alone. The camera's focal
  length (held by its prior where the user or EXIF gives one), principal point (held near the
  image centre, or near the one the user gave, by its prior), rotation and position are found by
  least squares, started from the best of a coarse search over headings, tilts and focal lengths
  (for each, the centre follows linearly from the points).

Both return the camera with the covariance of (f, cx, cy, ω, C), to first order: the camera is a
function of the marked pixels (1σ the click noise) and of the known points' positions, whose
joint covariance (``point_covariance``: the calibrated markers' σ, the solved model's covariance
carried to its vertices) is carried through that function beside the pixels'. Points given
without a covariance are taken as exact. ``Registered.prior_covariance`` keeps what the camera was
held by before any point: the vanishing-point calibration's (f, cx, cy, ω), or the principal
point's (and a given focal length's) prior, every other entry free (∞); a re-calibration holds
the photo by that alone, since its pins and sightings are in the re-calibration themselves
(docs/manual.md, "Modelling": registering further photos).

A photo's lens distortion, where it is known (the vanishing-point calibration's k1, or one given:
a lens profile, the user, an earlier calibration), is used as known and held: every marked pixel
is compared with the distorted projection of its point, and the start's rays are undistorted.
Registration does not estimate k1 (a handful of points cannot separate it from f); without one
the photo is registered as a pinhole, and ``vebuild solve --recalibrate`` may refine a k1 that has
a 1σ.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from vebuild.camera import (
    PINHOLE,
    Lens,
    exp_so3,
    intrinsic_matrix,
    pixel_rays_world,
    project,
    rotation_from_ypr,
    world_to_camera,
)
from vebuild.determinism import deterministic
from vebuild.errors import CalibrationError

from .lsq import (
    covariance_from_jacobian,
    numeric_failures,
    numeric_jacobian,
    photo_numeric_failures,
    variance_factor,
)
from .photo import FocalPrior, PhotoCalibration
from .priors import DistortionPrior, check_focal_prior, check_principal_point
from .start import intersect_lines

Array = NDArray[np.float64]

#: Coarse search of the start: headings every 30°, these tilts and these focal lengths (× the
#: image's longer side), which span hand-held photos from wide angle to short telephoto.
SEARCH_YAW_DEG = np.arange(0.0, 360.0, 30.0)
SEARCH_PITCH_DEG = (-50.0, -25.0, 0.0, 25.0)
SEARCH_FOCAL_REL = (0.6, 0.9, 1.3, 1.9, 2.8)


@dataclass(frozen=True)
class Registered:
    K: Array
    R: Array
    C: Array
    covariance: Array  # (9, 9) over (f, cx, cy, ω, C): from the pixels and the points
    residuals_px: Array  # (n, 2)
    method: str
    #: (9, 9) over (f, cx, cy, ω, C): the prior the registration held the camera by before any
    #: point (∞ on the diagonal where free; see the module).
    prior_covariance: Array = field(default_factory=lambda: np.diag(np.full(9, np.inf)))
    #: Where that prior is centred: K (its f the registered one where f is free) and R (the
    #: registered one where the rotation is free). None: the registered K and R.
    prior_K: Array | None = None
    prior_R: Array | None = None
    #: The lens distortion used (held): the division model's k1, its 1σ and where it came from
    #: ("" for a pinhole).
    k1: float = 0.0
    k1_sigma: float = 0.0
    k1_source: str = ""
    #: the lens's second term, held as calibrated (0: the one-term model)
    k2: float = 0.0


def _whitener(cov: Array) -> Array:
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    return (V / np.sqrt(np.maximum(w, 1e-18))).T


def _points_covariance(points: Array, point_covariance: ArrayLike | None) -> Array | None:
    """The (3n, 3n) joint covariance of the points, checked (None: exact)."""
    if point_covariance is None:
        return None
    S = np.asarray(point_covariance, float)
    n = 3 * len(points)
    if S.shape != (n, n) or not np.all(np.isfinite(S)):
        raise ValueError(f"point_covariance: expected a finite ({n}, {n}) matrix for {len(points)} points, "
                         f"got shape {S.shape}")
    return 0.5 * (S + S.T)


def _refine(points: Array, pixels: Array, K0: Array, R0: Array, C0: Array, click_sigma: float,
            prior: Array, prior_cov: Array, lens: Lens = PINHOLE,
            point_cov: Array | None = None) -> tuple[Array, Array, Array, Array, Array]:
    """Least squares over x = (f, cx, cy, ω, C), R = exp([ω]×) R0, with a Gaussian prior on the
    first six (intrinsics and rotation): mean ``prior``, covariance ``prior_cov`` (∞ = free); the
    pixels projected through the lens distortion ``lens`` (held).

    The covariance, to first order, of x̂(pixels, points): (JᵀJ)⁻¹ from the pixels, plus
    A Σ_X Aᵀ with A = −(JᵀJ)⁻¹ Jᵀ ∂r/∂X from the points' joint covariance ``point_cov`` (None:
    exact); scaled by the variance factor of the residuals whitened by the pixels' whole
    covariance (the clicks' and the points' carried into the image)."""
    free = ~np.isfinite(np.diag(prior_cov))
    held = np.flatnonzero(~free)
    L = _whitener(prior_cov[np.ix_(held, held)]) if len(held) else np.zeros((0, 0))

    def residuals(x: Array) -> Array:
        K = intrinsic_matrix(*x[:3])
        r = ((project(K, exp_so3(x[3:6]) @ R0, x[6:9], points, lens) - pixels) / click_sigma).ravel()
        return np.concatenate([r, L @ (x[held] - prior[held])])

    x0 = np.r_[K0[0, 0], K0[0, 2], K0[1, 2], 0.0, 0.0, 0.0, C0]
    sol = least_squares(residuals, x0, method="trf", x_scale="jac")
    R = exp_so3(sol.x[3:6]) @ R0
    # Re-linearise about the solution (ω = 0 there) for the covariance.
    prior_at = prior.copy()
    prior_at[3:6] -= sol.x[3:6]
    x_at = np.r_[sol.x[:3], 0.0, 0.0, 0.0, sol.x[6:9]]

    def res_at(x: Array) -> Array:
        K = intrinsic_matrix(*x[:3])
        r = ((project(K, exp_so3(x[3:6]) @ R, x[6:9], points, lens) - pixels) / click_sigma).ravel()
        return np.concatenate([r, L @ (x[held] - prior_at[held])])

    r = res_at(x_at)
    J = numeric_jacobian(res_at, x_at, 1e-6)
    cov = covariance_from_jacobian(J)
    n_pix = 2 * len(points)
    if point_cov is not None and np.any(point_cov):
        K_at, R_at = intrinsic_matrix(*x_at[:3]), R

        def pix_of_points(Xf: Array) -> Array:
            return (project(K_at, R_at, x_at[6:9], Xf.reshape(-1, 3), lens) / click_sigma).ravel()

        # ∂r/∂X of the whitened pixel rows (the priors do not depend on the points).
        Jx = numeric_jacobian(pix_of_points, points.ravel(), 1e-6)
        if np.all(np.isfinite(cov)):  # (an undetermined camera stays so)
            A = -cov @ J[:n_pix].T @ Jx
            cov = cov + A @ point_cov @ A.T
        # The pixel residuals' covariance (whitened units): the clicks' (I) and the points' carried.
        S = np.eye(n_pix) + Jx @ point_cov @ Jx.T
        rw = np.concatenate([_whitener(S) @ r[:n_pix], r[n_pix:]])
    else:
        rw = r
    cov = cov * variance_factor(rw, 9)
    K = intrinsic_matrix(*sol.x[:3])
    return K, R, sol.x[6:9].copy(), cov, project(K, R, sol.x[6:9], points, lens) - pixels


@deterministic
@photo_numeric_failures("its registration to the model", "check the marked points (at least 4, not all on one "
                        "line) and their known positions")
def register_from_points(points: ArrayLike, pixels: ArrayLike, width: int, height: int, *, photo: str = "photo",
                         click_sigma_px: float = 1.0, principal_point: tuple[ArrayLike, float] | None = None,
                         principal_point_sigma_rel: float = 0.01, focal: FocalPrior | None = None,
                         distortion: DistortionPrior | None = None,
                         point_covariance: ArrayLike | None = None) -> Registered:
    """A photo's whole camera from ≥ 4 points of known position and their pixels.

    ``point_covariance``: the points' joint (3n, 3n) covariance, in the order given (None: exact).

    ``focal``: a focal length given (the user's, or EXIF's), a prior with its 1σ and the search's
    only start; ``principal_point``: a known principal point and its 1σ (pixels), the prior's
    centre and 1σ (default the image centre, 1σ = ``principal_point_sigma_rel`` × the longer side);
    ``distortion``: the photo's lens distortion where it is known (held at its k1; None: a pinhole).
    """
    check_focal_prior(photo, "focal_px", focal)
    check_principal_point(photo, principal_point)
    k1 = 0.0 if distortion is None else float(distortion.k1)
    lens = Lens(k1)
    X = np.asarray(points, float).reshape(-1, 3)
    uv = np.asarray(pixels, float).reshape(-1, 2)
    S = _points_covariance(X, point_covariance)
    if len(X) < 4:
        raise CalibrationError(photo, f"registration without vanishing points needs at least 4 marked points of "
                               f"known position (model vertices or markers); this photo has {len(X)}")
    s = max(width, height)
    if principal_point is None:
        c = (width / 2.0, height / 2.0)
        pp_sigma = principal_point_sigma_rel * s
    else:
        u0, v0 = np.asarray(principal_point[0], float).reshape(2)
        c, pp_sigma = (float(u0), float(v0)), float(principal_point[1])
    focals = [focal.value] if focal is not None else [k * s for k in SEARCH_FOCAL_REL]
    best: list[tuple[float, Array, Array, Array]] = []
    for f in focals:
        K = intrinsic_matrix(f, *c)
        for yaw in SEARCH_YAW_DEG:
            for pitch in SEARCH_PITCH_DEG:
                R = rotation_from_ypr(np.radians(yaw), np.radians(pitch), 0.0)
                d = pixel_rays_world(K, R, uv, lens)
                C = intersect_lines(X, d)
                depth = world_to_camera(R, C, X)[:, 2]
                if np.any(depth <= 0):
                    continue
                err = float(np.sqrt(np.mean((project(K, R, C, X, lens) - uv) ** 2)))
                best.append((err, K, R, C))
    if not best:
        raise CalibrationError(photo, "no camera in front of all the marked points explains them; check that "
                               "the marked points are the right ones")
    best.sort(key=lambda t: t[0])
    # Priors: the principal point near the centre (or the one given); f from the user or EXIF if
    # known; ω free.
    prior = np.r_[0.0, c, 0.0, 0.0, 0.0]
    prior_cov = np.diag([np.inf, pp_sigma**2, pp_sigma**2, np.inf, np.inf, np.inf])
    if focal is not None:
        prior[0], prior_cov[0, 0] = focal.value, focal.sigma**2
    candidates: list[tuple[float, Array, Array, Array, Array, Array]] = []
    for _, K, R, C in best[:5]:
        Kr, Rr, Cr, cov, res = _refine(X, uv, K, R, C, click_sigma_px, prior, prior_cov, lens, S)
        candidates.append((float(np.sqrt(np.mean(res**2))), Kr, Rr, Cr, cov, res))
    rms, K, R, C, cov, res = min(candidates, key=lambda t: t[0])
    held = np.diag(np.full(9, np.inf))
    held[:6, :6] = prior_cov
    Kp = intrinsic_matrix(prior[0] if focal is not None else K[0, 0], *c)
    used = (k1, float(distortion.sigma), distortion.source) if distortion is not None else (0.0, 0.0, "")
    return Registered(K, R, C, cov, res, "points", held, Kp, R, *used)


@deterministic
def register_with_vanishing_points(cal: PhotoCalibration, points: ArrayLike, pixels: ArrayLike, *,
                                   click_sigma_px: float = 1.0,
                                   point_covariance: ArrayLike | None = None) -> Registered:
    """Position (and a refined rotation) of a photo whose K and R came from its vanishing points,
    from ≥ 2 points of known position, through the lens distortion its calibration found (held).
    ``point_covariance``: the points' joint (3n, 3n) covariance, in the order given (None: exact)."""
    # The calibration's k1 where it estimated one (its k1, k1_sigma, k1_source; 0 for a pinhole).
    k1, k1_sigma, k1_source = float(cal.k1), float(cal.k1_sigma), cal.k1_source
    lens = cal.lens  # with its k2, held as calibrated
    X = np.asarray(points, float).reshape(-1, 3)
    uv = np.asarray(pixels, float).reshape(-1, 2)
    S = _points_covariance(X, point_covariance)
    if len(X) < 2:
        raise CalibrationError(cal.photo, f"placing the camera needs at least 2 marked points of known position "
                               f"(model vertices or markers); this photo has {len(X)}")
    C0 = intersect_lines(X, pixel_rays_world(cal.K, cal.R, uv, lens))
    # Intrinsics and rotation held by their vanishing-point estimate and covariance.
    prior = np.r_[cal.f, cal.principal_point, 0.0, 0.0, 0.0]
    with numeric_failures(cal.photo, "placing the camera from its known points", "check the marked points "
                          "(not all on one line through the camera) and their known positions"):
        K, R, C, cov, res = _refine(X, uv, cal.K, cal.R, C0, click_sigma_px, prior, cal.covariance, lens, S)
    held = np.diag(np.full(9, np.inf))
    held[:6, :6] = cal.covariance
    if lens.is_pinhole:
        return Registered(K, R, C, cov, res, "vanishing points + points", held, cal.K, cal.R)
    return Registered(K, R, C, cov, res, "vanishing points + points", held, cal.K, cal.R, k1, k1_sigma,
                      k1_source if k1_source not in ("", "none") else "vanishing-point calibration", lens.k2)
