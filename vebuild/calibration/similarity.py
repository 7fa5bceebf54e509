"""A similarity transform (scale, rotation, translation) fitted between two sets of corresponding
points by Umeyama's least-squares method, with the covariance of its seven parameters.

Umeyama, "Least-squares estimation of transformation parameters between two point patterns"
(IEEE PAMI 13(4), 1991): the rotation from the SVD of the cross-covariance of the centred points
(its sign fixed so that it is a rotation, never a reflection), the scale from the singular values
over the source's variance, the translation from the centroids. It minimises
Σ ‖yᵢ − (s R xᵢ + t)‖².

Uncertainty (first order, from the residuals): the model ``yᵢ = s R xᵢ + t + eᵢ`` with eᵢ
independent, isotropic, of unknown variance σ² in the target frame, estimated as
σ̂² = Σ ‖rᵢ‖² / (3n − 7). The covariance of the parameters p = (s, ωx, ωy, ωz, tx, ty, tz) is
σ̂² (JᵀJ)⁻¹, J the Jacobian of the prediction at the solution, where ω is a small turn applied on
the target side, ``R = exp([ω]×) R̂`` (the convention of the cameras' ω, FORMAT.md). With three
targets the redundancy is 2: the estimate of σ is then poor, and the record says how many
redundant coordinates it rests on.

Layer 2 of DESIGN.md: numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

#: The names of the seven parameters, in the order of the covariance's rows.
PARAMETERS = ("scale", "omega_x", "omega_y", "omega_z", "t_x", "t_y", "t_z")
#: Targets within this share of the spread of the targets from a line are collinear: their
#: rotation about that line is not determined.
COLLINEAR_REL = 1e-6


class DegenerateTargets(ValueError):
    """Too few targets, or targets on a line (or on a point): no similarity is determined."""


@dataclass(frozen=True)
class Similarity:
    """``y = scale · rotation · x + translation``."""

    scale: float
    rotation: Array  # (3, 3), a proper rotation
    translation: Array  # (3,)

    def apply(self, x: ArrayLike) -> Array:
        X = np.asarray(x, float)
        return self.scale * X @ self.rotation.T + self.translation


@dataclass(frozen=True)
class SimilarityFit:
    """A fitted similarity, its residuals (target − prediction, per point), rms and covariance."""

    similarity: Similarity
    residuals: Array  # (n, 3)
    rms: float  # sqrt(mean ‖rᵢ‖²)
    sigma: float  # σ̂ per coordinate (NaN with no redundancy)
    redundancy: int  # 3n − 7
    covariance: Array  # (7, 7) over PARAMETERS


def check_targets(x: ArrayLike) -> None:
    """Raise DegenerateTargets where the points ``x`` cannot fix a similarity: fewer than three, or
    all on one line (the second singular value of the centred points below COLLINEAR_REL of the first)."""
    X = np.asarray(x, float).reshape(-1, 3)
    if len(X) < 3:
        raise DegenerateTargets(f"{len(X)} target{'s' if len(X) != 1 else ''}; a similarity needs at least 3 "
                                "targets not on one line")
    sv = np.linalg.svd(X - X.mean(axis=0), compute_uv=False)
    if sv[0] <= 0 or sv[1] <= COLLINEAR_REL * sv[0]:
        raise DegenerateTargets("the targets lie on one line (or on one point): the turn about that line is not "
                                "determined; add a target off the line")


def umeyama(x: ArrayLike, y: ArrayLike) -> Similarity:
    """The similarity that maps the points x onto y in the least-squares sense (module docstring)."""
    X, Y = np.asarray(x, float).reshape(-1, 3), np.asarray(y, float).reshape(-1, 3)
    if X.shape != Y.shape:
        raise ValueError(f"need as many source as target points, got {len(X)} and {len(Y)}")
    check_targets(X)
    check_targets(Y)
    mx, my = X.mean(axis=0), Y.mean(axis=0)
    Xc, Yc = X - mx, Y - my
    var_x = float(np.mean(np.sum(Xc**2, axis=1)))
    S = Yc.T @ Xc / len(X)
    U, D, Vt = np.linalg.svd(S)
    E = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        E[2, 2] = -1.0  # a reflection would fit better: the nearest rotation instead
    R = U @ E @ Vt
    s = float(np.trace(np.diag(D) @ E) / var_x)
    t = my - s * R @ mx
    return Similarity(s, R, t)


def _skew(v: Array) -> Array:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def jacobian(sim: Similarity, x: ArrayLike) -> Array:
    """(3n, 7): d(s R xᵢ + t)/d(s, ω, t) at ``sim``, ω a turn on the target side."""
    X = np.asarray(x, float).reshape(-1, 3)
    RX = X @ sim.rotation.T
    J = np.zeros((len(X), 3, 7))
    J[:, :, 0] = RX
    for i, p in enumerate(sim.scale * RX):
        J[i, :, 1:4] = -_skew(p)  # d(exp([ω]×) p)/dω at 0 = −[p]×
    J[:, :, 4:7] = np.eye(3)
    return J.reshape(-1, 7)


def fit_similarity(x: ArrayLike, y: ArrayLike) -> SimilarityFit:
    """Umeyama's similarity from x onto y, its residuals and the covariance of its parameters."""
    X, Y = np.asarray(x, float).reshape(-1, 3), np.asarray(y, float).reshape(-1, 3)
    sim = umeyama(X, Y)
    r = Y - sim.apply(X)
    ssr = float(np.sum(r**2))
    dof = 3 * len(X) - 7
    sigma2 = ssr / dof if dof > 0 else float("nan")
    J = jacobian(sim, X)
    cov = sigma2 * np.asarray(np.linalg.inv(J.T @ J), dtype=np.float64)
    return SimilarityFit(sim, r, float(np.sqrt(ssr / len(X))), float(np.sqrt(sigma2)), dof, cov)


def rotation_from_matrix(M: ArrayLike, tol: float = 1e-6) -> Array:
    """``M`` checked to be a rotation (orthonormal to ``tol``, determinant +1); raises ValueError."""
    R = np.asarray(M, float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ValueError("expected a 3×3 matrix of finite numbers")
    if np.abs(R @ R.T - np.eye(3)).max() > tol or np.linalg.det(R) < 0:
        raise ValueError("expected a rotation (orthonormal rows, determinant +1)")
    return R
