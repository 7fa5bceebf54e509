"""The solver's Jacobian checked against central differences of its residuals
(tests/test_model.py, tests/test_distortion_solver.py)."""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild.model.residuals import FD_STEP
from vebuild.synthetic import ROOM


def assert_jacobian_matches_differences(problem: Any, layout: Any, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Assert the solver's Jacobian at x equals central differences of its residuals within the
    bounds below; return both (J, F)."""
    J = problem.jacobian(x)
    J = J.toarray() if hasattr(J, "toarray") else np.asarray(J)
    h = 1e-5  # the reference's step: its own error, h²·|r‴|/6 + ε·|r|/h, stays below 1e-7 here
    F = np.empty_like(J)
    for j in range(layout.n):
        e = np.zeros(layout.n)
        e[j] = h
        F[:, j] = (problem.residuals(x + e) - problem.residuals(x - e)) / (2 * h)
    # The reference errs by h²·|r‴|/6 + ε·|r|/h: with |r‴| ≲ |r'|·(L/d)², L the longest lever (the
    # room's diagonal: the floor turns about the origin marker at its corner), d ≥ 1 m the nearest
    # depth. The analytic columns must agree within ten times that.
    lever = float(np.linalg.norm(ROOM))
    r = np.abs(problem.residuals(x))[:, None]
    tol = 10 * (h**2 * lever**2 * (1.0 + np.abs(F)) + np.finfo(float).eps * (1.0 + r) / h)
    # The solver differences the model's parameters, and the cameras' effect on edges, forward
    # over step = FD_STEP·max(1, |x|): an error of about ½·step·|r''|, |r''| ≲ |∇r|·L/d per unit of
    # the parameter, |∇r| the row's largest derivative: tolerance step·(1 + |∇r|)·L/(1 m).
    differenced = np.zeros(J.shape, bool)
    differenced[:, layout.model.slice] = True
    for b in layout.cameras.values():
        differenced[np.ix_(problem.rows_edge.ravel(), b.indices)] = True
    step = FD_STEP * np.maximum(1.0, np.abs(x))
    tol = np.where(differenced, step[None, :] * (1.0 + np.abs(F).max(axis=1, keepdims=True)) * lever, tol)
    worst = np.unravel_index(np.argmax(np.abs(J - F) / tol), J.shape)
    assert np.all(np.abs(J - F) <= tol), f"{problem.describe_row(int(worst[0]))}, {layout.names[worst[1]]}"
    return J, F
