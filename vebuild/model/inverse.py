"""Inverses of a solve's normal matrix (:mod:`vebuild.model.solution`'s covariances): dense, from
the Cholesky factor; and, where the cameras are among the unknowns (a re-calibrating solve), by
the Schur complement of the cameras' block.

No row of a solve joins two cameras: a pin, an edge or a marker sighting is in one photo, and a
camera's prior is its own. So the cameras' block of the normal matrix A is block diagonal (one
block per camera), and with r the other unknowns (the model's and the markers'):

    (A⁻¹)_rr = S⁻¹,  S = A_rr − Σ_c A_rc A_cc⁻¹ A_cr
    (A⁻¹)_cr = −A_cc⁻¹ A_cr S⁻¹
    (A⁻¹)_cc = A_cc⁻¹ + A_cc⁻¹ A_cr S⁻¹ A_rc A_cc⁻¹

each camera's terms touching only the unknowns it sees. On the house (2,459 unknowns, 936 of them
the cameras'), the dense inverse is 0.56 s on the solves' one thread, S⁻¹ alone 0.15 s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.linalg import cho_solve, solve_triangular

Array = NDArray[np.float64]


def inverse(A: Array | sparse.spmatrix) -> Array:
    """Inverse of a symmetric positive (semi-)definite normal matrix; ∞ where it is singular."""
    from scipy.linalg import lapack

    A = cast(Any, A).toarray() if sparse.issparse(A) else np.asarray(A, float)
    # Positive definite, as a normal matrix whose every unknown is observed is: from its Cholesky
    # factor (LAPACK potrf, potri), 0.86 s against 1.11 s by LU for a matrix of the house's 2,459
    # unknowns on the solves' one thread. Otherwise by LU, as before.
    L, info = lapack.dpotrf(A, lower=1, clean=1)  # the upper triangle zeroed, and left so by potri
    if info == 0:
        inv, info = lapack.dpotri(L, lower=1)
        if info == 0:
            full = inv + inv.T
            np.fill_diagonal(full, inv.diagonal())
            return np.asarray(full)
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        cov = np.linalg.pinv(A)
        cov[np.diag_indices_from(cov)] = np.inf
        return cov


@dataclass
class _Schur:
    """The Schur complement ``S`` of the cameras' block of A, over the unknowns ``r`` outside the
    cameras (``cam``: the cameras' unknowns); per camera its slice, the positions in ``r`` of the
    unknowns it touches, the Cholesky factor L of its block and W = L⁻¹ A_c,those."""

    r: NDArray[np.intp]
    cam: NDArray[np.intp]
    S: Array
    cameras: list[tuple[slice, NDArray[np.intp], NDArray[Any], NDArray[Any]]]


def _schur(A: Array, cameras: Sequence[slice]) -> _Schur | None:
    """The cameras' Schur complement of A; None where it does not apply: no cameras, two cameras
    joined, or a camera's block not positive definite."""
    n = A.shape[0]
    r = _rest(n, cameras)
    if not cameras or len(r) == n:
        return None
    cam = np.setdiff1d(np.arange(n), r)
    S = A[np.ix_(r, r)]
    parts = []
    for sl in cameras:
        block = A[sl]
        others = block[:, cam]
        own = np.zeros_like(others, bool)
        own[:, np.searchsorted(cam, np.arange(sl.start, sl.stop))] = True
        if np.any(others[~own] != 0.0):
            return None
        try:
            L = np.linalg.cholesky(block[:, sl])
        except np.linalg.LinAlgError:
            return None
        k = np.flatnonzero(np.any(block[:, r] != 0.0, axis=0))
        W = solve_triangular(L, block[:, r[k]], lower=True)  # A_k,c A_cc⁻¹ A_c,k = Wᵀ W
        if len(k):
            S[np.ix_(k, k)] -= W.T @ W
        parts.append((sl, k, L, W))
    return _Schur(r, cam, S, parts)


def _rest(n: int, cameras: Sequence[slice]) -> NDArray[np.intp]:
    rest = np.ones(n, bool)
    for sl in cameras:
        rest[sl] = False
    return np.flatnonzero(rest)


def outside_cameras_inverse(A: Array, cameras: Sequence[slice]) -> Array:
    """The block of A⁻¹ of the unknowns outside ``cameras`` (each camera's slice of the
    unknowns), in their order: S⁻¹; the whole inverse's block where the Schur complement does not
    apply."""
    A = np.asarray(A, float)
    sch = _schur(A, cameras)
    if sch is None:
        r = _rest(A.shape[0], cameras)
        return inverse(A)[np.ix_(r, r)]
    return inverse(sch.S)


def inverse_by_cameras(A: Array | sparse.spmatrix, cameras: Sequence[slice]) -> Array:
    """A⁻¹ (as :func:`inverse`) from the Schur complement of the cameras' block (each camera's
    slice of the unknowns): S⁻¹, then each camera's rows from its own terms. The whole inverse
    where the complement does not apply or S is singular (its ∞ where A is)."""
    A = cast(Any, A).toarray() if sparse.issparse(A) else np.asarray(A, float)
    sch = _schur(A, cameras)
    if sch is None:
        return inverse(A)
    Sinv = inverse(sch.S)
    if not np.all(np.isfinite(Sinv)):
        return inverse(A)
    n, r, cam = A.shape[0], sch.r, sch.cam
    at = np.full(n, -1)
    at[cam] = np.arange(len(cam))
    C = np.zeros((len(cam), len(r)))  # (A⁻¹)_cr = −A_cc⁻¹ A_cr S⁻¹, camera by camera
    X, rows_of = [], []
    for sl, k, L, W in sch.cameras:
        rows = slice(at[sl.start], at[sl.start] + (sl.stop - sl.start))  # the camera's rows of C
        Xc = solve_triangular(L.T, W, lower=False)  # A_cc⁻¹ A_c,k
        if len(k):
            C[rows] = -(Xc @ Sinv[k])
        X.append(Xc)
        rows_of.append(rows)
    CC = np.zeros((len(cam), len(cam)))  # (A⁻¹)_cc = A_cc⁻¹ + X S⁻¹ Xᵀ = A_cc⁻¹ − C_·,k Xᵀ
    for (sl, k, L, _), Xc, rows in zip(sch.cameras, X, rows_of, strict=True):
        if len(k):
            CC[:, rows] = -(C[:, k] @ Xc.T)
        CC[rows, rows] += cho_solve((L, True), np.eye(sl.stop - sl.start))
    out = np.empty((n, n))
    out[np.ix_(r, r)] = Sinv
    out[np.ix_(cam, r)] = C
    out[np.ix_(r, cam)] = C.T
    out[np.ix_(cam, cam)] = 0.5 * (CC + CC.T)
    return out
