"""The large problems' shortcuts give what the direct computations give: the joint placement's
sparse Jacobian and Levenberg–Marquardt loop, the covariance of a sparse Jacobian from its normal
matrix, and the model solver's Jacobian columns differenced in groups (docs/house.md)."""

from __future__ import annotations

import numpy as np
from scipy import sparse

from vebuild.calibration.lm import SPARSE_SOLVE_ABOVE, levenberg_marquardt
from vebuild.calibration.lsq import NORMAL_COVARIANCE_ABOVE, covariance_from_jacobian, numeric_jacobian
from vebuild.camera import ImageCamera
from vebuild.model.residuals import Pin
from vebuild.model.scene import model_from_dict
from vebuild.model.solver import Problem, ProblemOptions
from vebuild.synthetic import CLICK_NOISE_PX, model_scene

MARKERS = {"O": np.zeros(3)}


def _sparse_jacobian(n_cols: int, seed: int = 1) -> sparse.csr_matrix:
    """A block-sparse Jacobian as a placement's: many rows, each touching a few columns."""
    J = sparse.random(5 * n_cols, n_cols, density=8.0 / n_cols, random_state=seed, format="csr")
    return (J + sparse.eye(5 * n_cols, n_cols)).tocsr()


def test_a_sparse_jacobians_covariance_is_the_svds() -> None:
    """Above NORMAL_COVARIANCE_ABOVE unknowns the covariance comes from the normal matrix's Cholesky
    factor: the SVD's to rounding (1e-12 of its largest entry; condition numbers here are ~10)."""
    J = _sparse_jacobian(NORMAL_COVARIANCE_ABOVE + 100)
    fast = covariance_from_jacobian(J)
    exact = covariance_from_jacobian(J.toarray())
    assert np.abs(fast - exact).max() < 1e-12 * np.abs(exact).max()


def test_a_sparse_jacobians_undetermined_direction_still_gets_an_infinite_variance() -> None:
    """A column no row touches (a parameter nothing determines) sends the sparse Jacobian through
    the SVD's rule: ∞ for it, finite for the others; so does a column that copies another."""
    J = _sparse_jacobian(NORMAL_COVARIANCE_ABOVE + 100).tolil()
    J[:, 7] = 0.0
    cov = covariance_from_jacobian(J.tocsr())
    assert np.isinf(cov[7, 7]) and np.isfinite(cov[0, 0]) and np.isfinite(cov[8, 8])
    J = _sparse_jacobian(NORMAL_COVARIANCE_ABOVE + 100).tolil()
    J[:, 9] = J[:, 10]
    cov = covariance_from_jacobian(J.tocsr())
    assert np.isinf(cov[9, 9]) and np.isinf(cov[10, 10]) and np.isfinite(cov[0, 0])


def test_levenberg_marquardt_finds_the_same_minimum_with_a_sparse_system() -> None:
    """Above SPARSE_SOLVE_ABOVE unknowns the normal equations are solved as a sparse system: a
    nonlinear robust fit ends where the dense solve of the same problem ends (1e-8 of its scale)."""
    n = SPARSE_SOLVE_ABOVE + 50
    rng = np.random.default_rng(3)
    A = _sparse_jacobian(n, seed=2)
    truth = rng.normal(0.0, 1.0, n)
    b = A @ truth + 0.01 * np.sinh(A @ truth) + rng.normal(0.0, 0.1, A.shape[0])
    b[::50] += 5.0  # outliers, for the robust loss

    def fun(x: np.ndarray) -> np.ndarray:
        y = A @ x
        return y + 0.01 * np.sinh(y) - b

    def jac_sparse(x: np.ndarray) -> sparse.csr_matrix:
        return sparse.diags(1.0 + 0.01 * np.cosh(A @ x)) @ A

    def identity(x: np.ndarray) -> np.ndarray:
        return x

    kw = {"robust_rows": A.shape[0], "robust_scale": 1.0, "tol": 1e-12}
    a = levenberg_marquardt(fun, jac_sparse, np.zeros(n), identity, **kw)
    b_ = levenberg_marquardt(fun, lambda x: jac_sparse(x).toarray(), np.zeros(n), identity, **kw)
    assert a.converged and b_.converged
    assert np.abs(a.x - b_.x).max() < 1e-8 * np.abs(b_.x).max()


def _four_boxes() -> Problem:
    """Four boxes on a floor seen by three photos, pinned at the generator's click noise."""
    rng = np.random.default_rng(12)
    _, start, pins, photos = model_scene(rng, n_boxes=4, n_photos=3)
    cams = {p.id: ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height) for p in photos.values()}
    model = model_from_dict(start["nodes"], MARKERS)
    return Problem(model, cams, [Pin(p["photo"], p["node"], p["handle"], np.asarray(p["uv"])) for p in pins],
                   options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=1e5))


def test_the_grouped_jacobian_columns_are_each_parameters_own_difference() -> None:
    """Parameters that move no common node, distance or relation are differenced together; the
    Jacobian is bit for bit the one of a difference per parameter, and close to a central
    difference of the residuals (the handles move linearly per step: 1e-4 of the largest entry)."""
    problem = _four_boxes()
    groups = problem.column_groups
    assert sorted(j for g in groups for j in g) == list(problem.layout.model.indices)
    assert len(groups) < len(problem.layout.model.indices)  # four boxes on the floor share groups
    x = problem.x0()
    grouped = problem.jacobian(x)
    problem.column_groups = [[j] for g in groups for j in g]
    single = problem.jacobian(x)
    problem.column_groups = groups
    dense = [np.asarray(J.toarray() if sparse.issparse(J) else J) for J in (grouped, single)]
    assert np.array_equal(dense[0], dense[1])
    numeric = numeric_jacobian(problem.residuals, x, 1e-6)
    assert np.abs(dense[0] - numeric).max() < 1e-4 * np.abs(numeric).max()


def test_a_solve_is_plausible_only_where_every_node_fits() -> None:
    """Problem.plausible, on four boxes seen by three photos at the generator's click noise: the
    converged solve is plausible; one pin far out (a wrong click) leaves it so; one box whose pins
    are all tens of σ out (turned the wrong way among boxes that fit: the overall median does not
    move) is not, nor is a solve that did not converge."""
    import dataclasses

    problem = _four_boxes()
    result = problem.solve(problem.x0(), robust=True)
    assert result.converged and problem.plausible(result)
    rows = {n: problem.rows_pin[[i for i, p in enumerate(problem.pins) if p.node == n]]
            for n in {p.node for p in problem.pins}}
    fewest, most = sorted(rows, key=lambda n: len(rows[n]))[0], sorted(rows, key=lambda n: len(rows[n]))[-1]
    assert len(rows[fewest]) >= 3 and len(problem.pins) >= 5 * len(rows[fewest])
    one = result.residuals.copy()
    one[rows[most][0]] = 30.0
    assert problem.plausible(dataclasses.replace(result, residuals=one))
    turned = result.residuals.copy()
    turned[rows[fewest].ravel()] = 30.0
    assert np.median(np.hypot(*turned[problem.rows_pin].T)) < 2.0  # the overall median barely moves
    assert not problem.plausible(dataclasses.replace(result, residuals=turned))
    assert not problem.plausible(dataclasses.replace(result, converged=False))
