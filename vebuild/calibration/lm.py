"""The bounded Levenberg–Marquardt loop of the model solver (paper §3.1) and of the joint
placement of cameras and markers (:mod:`.positions`).

Not scipy's ``least_squares``: once the unknowns are many (a house's hundred cameras and hundreds
of markers) the normal equations are solved as a sparse system, where scipy's exact trust-region
step takes an SVD of the whole Jacobian at every iteration; the soft-L1 loss can be put on the
observation rows only (the model solver keeps it off its priors), where scipy's ``loss`` applies
to every row; and each step is projected onto the bounds (a size stays above its least, a hinge
at its stop stays there), where scipy's ``trf`` works in the interior with reflections.
``vebuild bench solver`` compares the two for speed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.constants import ROBUST_SCALE
from vebuild.determinism import deterministic

Array = NDArray[np.float64]

#: Above this many unknowns the normal equations are solved as a sparse system.
SPARSE_SOLVE_ABOVE = 400


@dataclass
class LMResult:
    """Where the loop ended: x, its cost, the number of iterations (each one Jacobian; a rejected
    step costs a residual evaluation more), whether it converged, and the whitened residuals at x."""

    x: Array
    cost: float
    iterations: int
    converged: bool
    residuals: Array


def spd_solve(A: Any, b: Array) -> Array:
    """x with A x = b for a sparse symmetric positive definite A (a damped normal matrix): SuperLU
    told the matrix is symmetric, so it orders the unknowns by the minimum degree of A + Aᵀ's
    pattern and keeps the diagonal pivots, which a positive definite matrix needs no others than.
    On the house's re-calibration (2,459 unknowns) 0.035 s a step against 0.12 s with SuperLU's
    default column order."""
    from scipy.sparse.linalg import splu

    lu = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return np.asarray(lu.solve(b))


@deterministic
def levenberg_marquardt(fun: Callable[[Array], Array], jac: Callable[[Array], Any], x0: Array,
                        clip: Callable[[Array], Array], max_iterations: int = 100, *,
                        robust_rows: int = 0, robust_scale: float = ROBUST_SCALE, tol: float = 1e-10,
                        damping: float = 1e-4) -> LMResult:
    """Minimise ½‖r(x)‖² (soft-L1 on the first ``robust_rows`` rows if given) over the x that
    ``clip`` leaves unchanged.

    Marquardt's scaled damping, each step projected by ``clip`` (the problem's: sizes stay above
    their least, each joint clips its own degrees of freedom to its limits), damping raised until a
    step lowers the cost. The robust loss is handled
    by iteratively reweighted least squares: row i is weighted by ρ'(rᵢ²/c²)^½.
    """
    from scipy import sparse  # imported at first use: docs/start-up.md

    x = clip(np.asarray(x0, float))

    def weights(r: Array) -> Array:
        w = np.ones_like(r)
        if robust_rows:
            z = (r[:robust_rows] / robust_scale) ** 2
            w[:robust_rows] = (1.0 + z) ** -0.25  # sqrt of ρ'(z) for ρ(z) = 2(√(1+z) − 1)
        return w

    def cost_of(r: Array) -> float:
        if not robust_rows:
            return 0.5 * float(r @ r)
        z = (r[:robust_rows] / robust_scale) ** 2
        rest = r[robust_rows:]
        return float(robust_scale**2 * np.sum(np.sqrt(1.0 + z) - 1.0) + 0.5 * rest @ rest)

    r = fun(x)
    cost = cost_of(r)
    lam = None
    it = 0
    converged = False
    while it < max_iterations:
        it += 1
        J = jac(x)
        w = weights(r)
        Jw = sparse.diags(w) @ J if sparse.issparse(J) else J * w[:, None]
        A = Jw.T @ Jw
        # Few unknowns: a dense solve. Many (hundreds of primitives): the normal matrix is sparse
        # (a primitive couples only with its cameras and ancestors), so a sparse LU keeps the
        # cost growing with the number of primitives rather than its cube.
        use_sparse = sparse.issparse(A) and A.shape[0] > SPARSE_SOLVE_ABOVE
        if not use_sparse and sparse.issparse(A):
            A = A.toarray()
        g = Jw.T @ (w * r)
        d = np.maximum(A.diagonal(), 1e-12)
        if lam is None:
            lam = damping
        improved = False
        for _ in range(30):
            try:
                if use_sparse:
                    step = -spd_solve(A + sparse.diags(lam * d), g)
                    if not np.all(np.isfinite(step)):
                        raise np.linalg.LinAlgError
                else:
                    step = -np.linalg.solve(A + lam * np.diag(d), g)
            except (np.linalg.LinAlgError, RuntimeError):
                lam *= 10.0
                continue
            x_new = clip(x + step)
            r_new = fun(x_new)
            c_new = cost_of(r_new)
            if c_new <= cost:
                improved = True
                break
            lam *= 10.0
        if not improved:
            converged = True  # no step lowers the cost: at a minimum within the bounds
            break
        dx = x_new - x
        small_step = np.linalg.norm(dx) <= tol * (np.linalg.norm(x) + tol)
        small_gain = cost - c_new <= tol * max(cost, 1e-30)
        x, r, cost = x_new, r_new, c_new
        lam = max(lam / 10.0, 1e-12)
        if small_step or small_gain:
            converged = True
            break
    return LMResult(x, cost, it, converged, r)

