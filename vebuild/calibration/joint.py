"""The joint least-squares problem of one photo's calibration, and the test of a mislabelled axis.

:func:`vebuild.calibration.photo.calibrate_photo` states the problem (:class:`JointProblem`: f, c,
the rotation and the lens distortion (k1, and k2 where one term is not enough) against every clicked
point of every vanishing segment, with the priors) and decides from its answers;
:func:`check_orthogonal_pairs` is the refusal of two vanishing points that no real focal length
makes orthogonal.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import Lens, exp_so3, intrinsic_matrix, undistort_pixels
from vebuild.errors import CalibrationError

from .intrinsics import focal_squared
from .lsq import covariance_from_jacobian, numeric_jacobian
from .priors import DistortionPrior, FocalPrior
from .vanishing import VanishingPointFit, segment_residuals, tangent_basis

Array = NDArray[np.float64]

#: Two vanishing points give f² ≤ 0 *significantly* (a mislabelled set, not a near-infinite point
#: on the far side of infinity) when f² w₁w₂ (a smooth function of the points on the sphere, ≤ 0
#: exactly where no real f fits) lies this many of its 1σ below zero.
MISLABEL_SIGMAS = 3.0
#: The stated click noise is trusted unless the marks reject it: the variance factor stays 1 while
#: χ² lies below this quantile of its distribution, and is χ²/dof beyond (the global test of a
#: least-squares adjustment). Flooring at 1 alone reports too much uncertainty on the few segments
#: a photo has (dof ~ 10: χ²/dof exceeds 1 half the time), taking the 95 % intervals' coverage of
#: the truth to ~98 %.
VARIANCE_TEST_QUANTILE = 0.95
#: Variance of a segment residual for isotropic click noise σ on each end point: the distance of
#: an end point to the line through the midpoint is ½(n₁ − n₂)⊥, so its variance is σ²/2. (The
#: joint solve keeps both end points' residuals, each of variance σ², an identical objective that
#: extends to polylines.)
SEGMENT_RESIDUAL_VARIANCE_FACTOR = 0.5


def check_orthogonal_pairs(fits: Mapping[str, VanishingPointFit], segs: Mapping[str, Array], axes: list[str],
                            N: Array, c0: Array, sigma_c: float, click_sigma_px: float,
                            photo: str, given_principal_point: bool = False) -> CalibrationError | None:
    """The refusal of a pair of vanishing points that no real focal length makes orthogonal, or None.

    f² = −(v₁ − c)·(v₂ − c) for finite points; on the sphere of normalised homogeneous points x =
    (p, w), q = −(p₁ − c w₁)·(p₂ − c w₂) · w₁ w₂ = f² w₁² w₂² has f²'s sign, is smooth through
    w = 0 (a point at infinity) and does not change when either point flips sign. A near-infinite
    point on the "wrong side" has q ≈ 0 within its noise; a mislabelled set has q well below 0.
    The end points' vanishing points know nothing of lens distortion, which can tip a pair of
    near-infinite points: the caller refuses only where the joint solve (which models it) cannot
    fit orthogonal directions either.
    """
    c = (N @ np.r_[c0, 1.0])[:2]
    sc = N[0, 0] * sigma_c
    N_inv = np.linalg.inv(N)
    tangents, covs = {}, {}
    for a in axes:
        x = N @ fits[a].point
        x = x / np.linalg.norm(x)
        t1, t2 = tangent_basis(x)
        T = np.column_stack([t1, t2])

        def res(ab: Array, x: Array = x, T: Array = T, a: str = a) -> Array:
            p = x + T @ ab
            return segment_residuals(N_inv @ (p / np.linalg.norm(p)), segs[a])

        Jv = numeric_jacobian(res, np.zeros(2), 1e-7) / (click_sigma_px * np.sqrt(SEGMENT_RESIDUAL_VARIANCE_FACTOR))
        info = Jv.T @ Jv
        tangents[a] = (x, T)
        # Widened by how much worse than the click noise the segments fit their point (an
        # unmodelled lens distortion shows there): the check is then no surer than the marks.
        r = res(np.zeros(2)) / (click_sigma_px * np.sqrt(SEGMENT_RESIDUAL_VARIANCE_FACTOR))
        vf = max(1.0, float(r @ r) / (len(r) - 2)) if len(r) > 2 else 1.0
        covs[a] = np.linalg.pinv(info) * vf
    for a, b in combinations(axes, 2):
        (xa, Ta), (xb, Tb) = tangents[a], tangents[b]

        def q(z: Array, xa: Array = xa, Ta: Array = Ta, xb: Array = xb, Tb: Array = Tb) -> Array:
            pa = xa + Ta @ z[0:2]
            pb = xb + Tb @ z[2:4]
            pa, pb = pa / np.linalg.norm(pa), pb / np.linalg.norm(pb)
            cc = c + z[4:6]
            return np.array([-float((pa[:2] - cc * pa[2]) @ (pb[:2] - cc * pb[2])) * pa[2] * pb[2]])

        z0 = np.zeros(6)
        g = numeric_jacobian(q, z0, 1e-7)[0]
        cov = np.zeros((6, 6))
        cov[0:2, 0:2], cov[2:4, 2:4], cov[4:6, 4:6] = covs[a], covs[b], np.eye(2) * sc**2
        q0 = float(q(z0)[0])
        sq = float(np.sqrt(max(g @ cov @ g, 0.0)))
        # A point that may lie at infinity (w within its noise of 0) may cross it, and q with it:
        # the linearised σ of q does not see that where both points are near infinity.
        may_be_infinite = any(abs(x[2]) < MISLABEL_SIGMAS * np.sqrt(max(T[2] @ covs[k] @ T[2], 0.0))
                              for k, (x, T) in ((a, tangents[a]), (b, tangents[b])))
        if not may_be_infinite and q0 + MISLABEL_SIGMAS * sq < 0:
            pa, pb = fits[a].finite_point(), fits[b].finite_point()
            f2 = focal_squared(pa, pb, c0) if pa is not None and pb is not None else -np.inf
            return CalibrationError(
                photo,
                f"the vanishing points of axes {a} and {b} give f² = {f2:.4g} px² ≤ 0: for orthogonal "
                "directions they must lie on opposite sides of the principal point; "
                + (f"the principal point given for the photo ({c0[0]:.1f}, {c0[1]:.1f} ± {sigma_c:.1f} px) is wrong, "
                   "or a segment set is labelled with the wrong axis: check its principal_point, then the axes"
                   if given_principal_point else "a segment set is probably labelled with the wrong axis"),
            )
    return None


class JointProblem:
    """The joint least-squares problem over y = (f/s, cx/s, cy/s, ω, [k1, [k2]]), R = exp([ω]×) R̂.

    Every clicked point is undistorted (division model, closed form) with the current f, c, k1, k2;
    its residual is its distance to the line joining the vanishing point K R eₐ to the centroid of
    its polyline's undistorted points, weighted by 1/σ (a polyline of m points has m − 1
    independent residuals: they sum to zero).
    """

    def __init__(self, polys: Mapping[str, list[Array]], axes: list[str], sigma_px: float | Mapping[str, Array],
                 scale: float, c0: Array, sigma_c: float, k1_prior: DistortionPrior | None, estimate_k1: bool,
                 estimate_k2: bool = False):
        """sigma_px: 1σ of every point, or axis → one 1σ per polyline (a detected segment's own)."""
        self.axes, self.scale, self.c0, self.sigma_c = axes, scale, c0, sigma_c
        self.k1_prior, self.estimate_k1 = k1_prior, estimate_k1
        #: k1 where it is not estimated: 0, or the value it is held at (.bending).
        self.k1_fixed = 0.0
        #: k2 (the second term, estimated only with k1, where one term does not straighten the lines:
        #: .bending) where it is not estimated: 0.
        self.estimate_k2 = estimate_k2 and estimate_k1
        self.k2_fixed = 0.0
        pts: list[Array] = []
        pid: list[Array] = []
        axis_of: list[int] = []
        first: list[int] = []
        self.polys_of: dict[str, list[int]] = {}
        for a in axes:
            for p in polys[a]:
                self.polys_of.setdefault(a, []).append(len(axis_of))
                first.append(int(sum(len(q) for q in pts)))
                pid.append(np.full(len(p), len(axis_of)))
                axis_of.append("xyz".index(a))
                pts.append(np.asarray(p, float))
        self.P = np.concatenate(pts)
        self.pid = np.concatenate(pid)
        self.axis_of = np.array(axis_of)
        self.first = np.array(first)
        self.counts = np.bincount(self.pid).astype(float)
        self.n_data = len(self.P)
        self.n_independent = int(self.n_data - len(self.counts))
        self.n_params = 6 + int(estimate_k1) + int(self.estimate_k2)
        if isinstance(sigma_px, Mapping):
            per_poly = np.concatenate([np.asarray(sigma_px[a], float).reshape(-1) for a in axes])
            self.weight = 1.0 / per_poly[self.pid]
        else:
            self.weight = np.full(self.n_data, 1.0 / float(sigma_px))

    def start(self, f0: float, c: Array) -> Array:
        k1 = self.k1_prior.k1 if self.k1_prior is not None else self.k1_fixed
        return np.r_[f0 / self.scale, np.asarray(c) / self.scale, 0.0, 0.0, 0.0, [k1] if self.estimate_k1 else [],
                     [self.k2_fixed] if self.estimate_k2 else []]

    def k1_of(self, y: Array) -> float:
        return float(y[6]) if self.estimate_k1 else self.k1_fixed

    def k2_of(self, y: Array) -> float:
        return float(y[7]) if self.estimate_k2 else self.k2_fixed

    def lens_of(self, y: Array) -> Lens:
        return Lens(self.k1_of(y), self.k2_of(y))

    def at_rotation(self, y: Array) -> Array:
        """y with ω = 0: the rotation is then the R it was solved to."""
        z = np.array(y, float)
        z[3:6] = 0.0
        return z

    def undistorted(self, y: Array) -> Array:
        lens = self.lens_of(y)
        if lens.is_pinhole:
            return self.P
        return undistort_pixels(intrinsic_matrix(*(y[:3] * self.scale)), self.P, lens)

    def _point_residuals(self, U: Array, V: Array) -> Array:
        """Distance of each undistorted point to its polyline's line centroid–vanishing point.

        V : (3, 3) the vanishing points of x, y, z as columns (homogeneous pixels)."""
        mx = np.bincount(self.pid, U[:, 0]) / self.counts
        my = np.bincount(self.pid, U[:, 1]) / self.counts
        v = V[:, self.axis_of]  # (3, n_poly)
        # l = (mx, my, 1) × v
        l0 = my * v[2] - v[1]
        l1 = v[0] - mx * v[2]
        l2 = mx * v[1] - my * v[0]
        norm = np.maximum(np.hypot(l0, l1), 1e-300)
        return (l0[self.pid] * U[:, 0] + l1[self.pid] * U[:, 1] + l2[self.pid]) / norm[self.pid]

    def _noise_scale(self, y: Array, U: Array, V: Array) -> Array:
        """How much undistorting a point stretches its click noise across its line: |Jᵀn| with J
        the Jacobian of x_u = x_d / (1 + k1 r² + k2 r⁴), n the line's unit normal (1 for a pinhole).
        A barrel lens's undistortion stretches the corners by a few per cent; weighting those
        residuals by 1/σ alone would claim that much more certainty than the clicks have."""
        k1, k2 = self.k1_of(y), self.k2_of(y)
        if k1 == 0.0 and k2 == 0.0:
            return np.ones(len(U))
        f, cx, cy = y[:3] * self.scale
        xd = (self.P - np.array([cx, cy])) / f
        r2 = np.sum(xd**2, axis=1)
        d = 1.0 + k1 * r2 + k2 * r2**2
        mx = np.bincount(self.pid, U[:, 0]) / self.counts
        my = np.bincount(self.pid, U[:, 1]) / self.counts
        v = V[:, self.axis_of]
        n = np.stack([my * v[2] - v[1], v[0] - mx * v[2]], axis=1)
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
        n = n[self.pid]
        # Jᵀn = (n − (2 k1 + 4 k2 r²) x (x·n) / d) / d  (J is symmetric)
        jn = (n - ((2.0 * k1 + 4.0 * k2 * r2) / d)[:, None] * xd * np.sum(xd * n, axis=1)[:, None]) / d[:, None]
        return np.asarray(np.linalg.norm(jn, axis=1), float)

    def residuals(self, y: Array, R0: Array, prior_f: FocalPrior | None) -> Array:
        f, cx, cy = y[:3] * self.scale
        K = intrinsic_matrix(f, cx, cy)
        R = exp_so3(y[3:6]) @ R0
        U = self.undistorted(y)
        V = K @ R
        parts = [self._point_residuals(U, V) * self.weight / self._noise_scale(y, U, V),
                 (np.array([cx, cy]) - self.c0) / self.sigma_c]
        if self.k1_prior is not None:
            parts.append(np.array([(self.k1_of(y) - self.k1_prior.k1) / self.k1_prior.sigma]))
        if prior_f is not None:
            parts.append(np.array([(f - prior_f.value) / prior_f.sigma]))
        return np.concatenate(parts)

    def cost(self, y: Array, R: Array, prior_f: FocalPrior | None) -> float:
        """The sum of the squared residuals (each over its 1σ) at a solution (y, R)."""
        r = self.residuals(self.at_rotation(y), R, prior_f)
        return float(r @ r)

    def solve(self, y0: Array, R0: Array, prior_f: FocalPrior | None) -> tuple[Array, Array]:
        from scipy.optimize import least_squares  # imported at first use: docs/start-up.md

        y0 = self.at_rotation(y0)
        lens = [np.inf] * (self.n_params - 6)
        lower = np.r_[1e-3, -np.inf, -np.inf, -np.pi, -np.pi, -np.pi, np.negative(lens)]
        upper = np.r_[1e3, np.inf, np.inf, np.pi, np.pi, np.pi, lens]
        sol = least_squares(
            self.residuals, y0, args=(R0, prior_f), bounds=(lower, upper), method="trf", x_scale="jac",
            xtol=1e-12, ftol=1e-12, gtol=1e-12,
        )
        R = exp_so3(sol.x[3:6]) @ R0
        return self.at_rotation(sol.x), R

    def jacobian(self, y: Array, R: Array, prior_f: FocalPrior | None) -> Array:
        return numeric_jacobian(lambda z: self.residuals(z, R, prior_f), self.at_rotation(y), 1e-7)

    def segment_information(self, y: Array, R: Array) -> tuple[float, float]:
        """1σ (pixels; inf if none) of f from the segments with the principal point's and the lens
        profile's priors, and of c (largest axis) from the segments with the lens profile's only."""
        J = self.jacobian(y, R, None)
        n = self.n_data
        sigma_f = _marginal_sigma(J.T @ J, 0) * self.scale
        rows = np.r_[np.arange(n), np.arange(n + 2, len(J))]  # without the principal point's prior
        Jd = J[rows]
        cov = _safe_inverse(Jd.T @ Jd)
        if cov is None:
            sigma_c = np.inf
        else:
            sigma_c = float(np.sqrt(max(np.linalg.eigvalsh(cov[1:3, 1:3]).max(), 0.0))) * self.scale
        return sigma_f, sigma_c

    def variance_factor(self, J: Array, r: Array, intervals: bool = False, tested: bool = True) -> float:
        """σ0²: 1 unless the marks reject the stated click noise (VARIANCE_TEST_QUANTILE), else χ²/dof.

        dof counts the independent residuals less the parameters the marks determine (the trace of
        the hat matrix of the data rows: a parameter fixed by its prior uses none of them). With
        ``intervals``, a σ0² estimated from the marks is widened by (t₀.₉₇₅,dof / z₀.₉₇₅)²: an
        interval whose variance is estimated from dof residuals is Student's t, not normal, so that
        ± 1.96σ then holds 95 % (1.29× the variance at dof = 10, 1.03× at 100). Not ``tested``
        (where segments were rejected as clutter: the rest may hold clutter too small to reject
        one by one), any excess over the stated noise is taken as measured, without the test."""
        from scipy.stats import chi2, norm, t  # imported at first use: docs/start-up.md

        n = self.n_data
        cov = _safe_inverse(J.T @ J)
        if cov is None:
            return 1.0
        used = float(np.trace(J[:n] @ cov @ J[:n].T))
        dof = self.n_independent - used
        if dof <= 0.5:
            return 1.0
        x2 = float(r[:n] @ r[:n])
        if x2 <= (chi2.ppf(VARIANCE_TEST_QUANTILE, dof) if tested else dof):
            return 1.0
        return x2 / dof * (float(t.ppf(0.975, dof) / norm.ppf(0.975)) ** 2 if intervals else 1.0)

    def covariance(self, J: Array, vf: float) -> Array:
        """(8, 8) covariance of y with the data rows' noise widened by vf (the priors' σ are stated,
        not scaled); k1's and k2's rows and columns 0 where they are fixed."""
        Jw = np.array(J, float)
        Jw[: self.n_data] /= np.sqrt(vf)
        cov = covariance_from_jacobian(Jw)
        out = np.zeros((8, 8))
        out[: self.n_params, : self.n_params] = cov
        return out

    def reported_residuals(self, U: Array, axis: str, v: Array) -> Array:
        """One value per segment of ``axis``: the RMS of its points' distances to the line through
        its centroid and v, signed as its first point's (the paper's residual for two points)."""
        V = np.zeros((3, 3))
        V[:, "xyz".index(axis)] = v
        ids = self.polys_of[axis]
        r = self._point_residuals(U, V)
        out = []
        for k in ids:
            rk = r[self.pid == k]
            out.append(np.sign(r[self.first[k]]) * np.sqrt(np.mean(rk**2)))
        return np.array(out)


@dataclass(frozen=True)
class LinesAlone:
    """A photo's solution with no focal prior: what its lines alone say about f.

    sigma_f_seg, sigma_c_seg : JointProblem.segment_information there (pixels); vf : the marks'
    variance factor there; cost : the sum of the squared (whitened) residuals there; sigma_f :
    sigma_f_seg widened by √vf where the marks fit worse than the stated click noise."""

    y: Array
    R: Array
    sigma_f_seg: float
    sigma_c_seg: float
    vf: float
    cost: float
    scale: float

    @property
    def f(self) -> float:
        return float(self.y[0] * self.scale)

    @property
    def rel_sigma_f_seg(self) -> float:
        return self.sigma_f_seg / self.f

    @property
    def sigma_f(self) -> float:
        return float(self.sigma_f_seg * np.sqrt(max(self.vf, 1.0)))


def lines_alone(problem: JointProblem, y: Array, R: Array) -> LinesAlone:
    """The solution without a focal prior, solved from (y, R)."""
    y, R = problem.solve(y, R, None)
    sigma_f_seg, sigma_c_seg = problem.segment_information(y, R)
    J = problem.jacobian(y, R, None)
    r = problem.residuals(problem.at_rotation(y), R, None)
    return LinesAlone(y, R, sigma_f_seg, sigma_c_seg, problem.variance_factor(J, r), float(r @ r), problem.scale)


def _safe_inverse(info: Array) -> Array | None:
    w = np.linalg.eigvalsh(info)
    if w.min() <= 1e-12 * max(w.max(), 1e-300):
        return None
    return np.asarray(np.linalg.inv(info), float)


def _marginal_sigma(info: Array, which: int) -> float:
    cov = _safe_inverse(info)
    if cov is None:
        return np.inf
    return float(np.sqrt(cov[which, which]))
