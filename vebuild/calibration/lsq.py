"""Small helpers shared by the calibration solvers: Jacobians and covariances."""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
F = TypeVar("F", bound=Callable[..., Any])


def numeric_jacobian(fun: Callable[[Array], Array], x: Array, step: Array | float = 1e-6) -> Array:
    """Central-difference Jacobian of fun at x, shape (m, n)."""
    x = np.asarray(x, float)
    h = np.broadcast_to(np.asarray(step, float), x.shape)
    cols = []
    for i in range(x.size):
        dx = np.zeros_like(x)
        dx[i] = h[i]
        cols.append((fun(x + dx) - fun(x - dx)) / (2 * h[i]))
    return np.column_stack(cols)


#: Above this many unknowns a sparse Jacobian's covariance is taken from its normal matrix where
#: that is well conditioned (:func:`covariance_from_jacobian`); the SVD of J is then seconds.
NORMAL_COVARIANCE_ABOVE = 400
#: The least reciprocal condition number of the column-scaled normal matrix inverted directly; a
#: worse one (singular values of the scaled J spread over more than 10⁶) goes through the SVD.
NORMAL_RCOND_MIN = 1e-12


def covariance_from_jacobian(J: Any) -> Array:
    """(JᵀJ)⁻¹ for whitened residuals, through the SVD of J for numerical stability.

    Directions that the data do not determine (singular values below 1e-10 of the largest) get an
    infinite variance, so that no reported 1σ is silently small or NaN.

    J may be a SciPy sparse matrix. With many unknowns (a house's cameras and markers) the SVD of J
    costs seconds, so the normal matrix JᵀJ, its columns scaled to a unit diagonal, is inverted by
    its Cholesky factor instead wherever it is well conditioned (:data:`NORMAL_RCOND_MIN`, LAPACK's
    estimate): every direction is then determined, and the inverse is the SVD's to rounding. A
    worse one goes through the SVD and its rule.
    """
    from scipy import sparse

    if sparse.issparse(J):
        if J.shape[1] > NORMAL_COVARIANCE_ABOVE:
            cov = _covariance_from_normal_matrix(J)
            if cov is not None:
                return cov
        J = J.toarray()
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    ok = s > 1e-10 * s.max()
    cov = (Vt[ok].T / s[ok] ** 2) @ Vt[ok]
    if not np.all(ok):
        undetermined = np.any(np.abs(Vt[~ok]) > 1e-6, axis=0)
        cov[undetermined, :] = np.inf
        cov[:, undetermined] = np.inf
    return cov


def _covariance_from_normal_matrix(J: Any) -> Array | None:
    """(JᵀJ)⁻¹ by a Cholesky factor of the column-scaled normal matrix; None where a column is
    empty, the factor fails or the matrix is worse conditioned than :data:`NORMAL_RCOND_MIN`."""
    from scipy.linalg import LinAlgError, cho_factor, cho_solve, lapack

    N = np.asarray((J.T @ J).toarray(), float)
    d = np.sqrt(np.diag(N))
    if not np.all(d > 0) or not np.all(np.isfinite(N)):
        return None
    Ns = N / d[:, None] / d[None, :]
    try:
        c, lower = cho_factor(Ns, lower=False, check_finite=False)
    except LinAlgError:
        return None
    rcond, info = lapack.dpocon(c, float(np.abs(Ns).sum(axis=0).max()))  # c is the upper factor
    if info != 0 or not rcond >= NORMAL_RCOND_MIN:
        return None
    inv = cho_solve((c, lower), np.eye(len(d)), check_finite=False)
    cov: Array = inv / d[:, None] / d[None, :]
    return 0.5 * (cov + cov.T)


def propagated_variance(g: Array, cov: Array) -> float:
    """gᵀ C g, the variance of a function with gradient ``g``, over the parameters it depends on only.

    A covariance from :func:`covariance_from_jacobian` holds ∞ for what the data do not determine
    (a marker seen in one photo); a quantity that does not depend on those parameters keeps its
    finite variance (the full product would give 0 · ∞ = NaN), one that does gets ∞.
    """
    g = np.asarray(g, float)
    idx = np.flatnonzero(g)
    if idx.size == 0:
        return 0.0
    sub = cov[np.ix_(idx, idx)]
    if not np.all(np.isfinite(sub)):
        return float("inf")
    return max(float(g[idx] @ sub @ g[idx]), 0.0)


#: Below this redundancy (the least eigenvalue of I − H over one observation's rows) an observation
#: is not tested: the others barely say where it should be, so no offset from them is measured.
MIN_REDUNDANCY = 0.01


def offsets_from_the_others(J_rows: Any, cov_unscaled: Array, whitened: Array) -> tuple[Array, Array]:
    """Per observation of ``whitened`` (n, 2) residuals (rows 2j, 2j+1 of ``J_rows``, the whitened
    Jacobian; ``cov_unscaled`` = (JᵀJ)⁻¹ over all rows): its offset from where the other
    observations put it, (I − H)⁻¹ r with H = J_o C J_oᵀ its 2 × 2 hat block (the deleted
    residual, in units of the stated noise), and the test statistic rᵀ (I − H)⁻¹ r, χ² with 2
    degrees of freedom for an honest observation (NaN where its redundancy is below MIN_REDUNDANCY)."""
    from scipy import sparse

    n = len(whitened)
    Js = sparse.csr_matrix(J_rows)
    A = np.asarray(Js @ cov_unscaled)  # (2n, p), dense; J stays sparse
    J0, J1 = Js[0::2], Js[1::2]
    h00 = np.asarray(J0.multiply(A[0::2]).sum(axis=1)).ravel()
    h11 = np.asarray(J1.multiply(A[1::2]).sum(axis=1)).ravel()
    h01 = np.asarray(J1.multiply(A[0::2]).sum(axis=1)).ravel()
    M = np.empty((n, 2, 2))
    M[:, 0, 0], M[:, 1, 1] = 1.0 - h00, 1.0 - h11
    M[:, 0, 1] = M[:, 1, 0] = -h01
    offsets = np.full((n, 2), np.nan)
    stat = np.full(n, np.nan)
    for j in range(n):
        if np.min(np.linalg.eigvalsh(M[j])) >= MIN_REDUNDANCY:
            offsets[j] = np.linalg.solve(M[j], whitened[j])
            stat[j] = float(whitened[j] @ offsets[j])
    return offsets, stat


def variance_factor(whitened_residuals: Array, n_params: float) -> float:
    """A-posteriori variance factor σ0² = χ² / dof, floored at 1.

    Floored so that reported uncertainties are never smaller than the stated click noise implies;
    raised when the marks fit worse than that noise.
    """
    dof = whitened_residuals.size - n_params
    if dof <= 0:
        return 1.0
    return max(1.0, float(whitened_residuals @ whitened_residuals) / dof)


def is_numeric_failure(e: BaseException) -> bool:
    """A NumPy/SciPy failure caused by the numbers given (not a bug): a singular matrix, or
    residuals, Jacobians or arrays that are not finite."""
    if isinstance(e, np.linalg.LinAlgError):
        return True
    # Whole words: "infs or NaNs", "not finite", "inf" — not "infeasible" (a bound, not the numbers).
    words = set(re.findall(r"[a-z]+", str(e).lower()))
    return isinstance(e, ValueError) and bool(words & {"finite", "nonfinite", "nan", "nans", "inf", "infs", "infinite",
                                                       "infinity"})


@contextmanager
def numeric_failures(photo: str | None, what: str, advice: str) -> Iterator[None]:
    """Turn a numeric failure inside the block into a CalibrationError naming ``photo`` (or None)
    and ``what`` failed, with ``advice``; other errors pass unchanged."""
    from vebuild.errors import CalibrationError, VebuildError

    try:
        yield
    except VebuildError:
        raise
    except (ValueError, np.linalg.LinAlgError) as e:
        if not is_numeric_failure(e):
            raise
        raise CalibrationError(photo, f"{what} failed numerically ({e}); {advice}") from None


def photo_numeric_failures(what: str, advice: str) -> Callable[[F], F]:
    """Decorator: :func:`numeric_failures` around a function whose ``photo`` keyword names the photo."""
    def wrap(fn: F) -> F:
        @functools.wraps(fn)
        def inner(*args: Any, **kwargs: Any) -> Any:
            with numeric_failures(kwargs.get("photo", "photo"), what, advice):
                return fn(*args, **kwargs)
        return inner  # type: ignore[return-value]
    return wrap
