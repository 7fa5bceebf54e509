"""What a model solve found (paper §3.1, §3.2): covariance, residuals per observation, outliers,
undetermined parameters, the re-calibrated cameras and markers, and the handles' covariances.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from ..calibration.lsq import variance_factor
from ..camera import ImageCamera
from ..constants import OUTLIER_SIGMAS
from ..determinism import deterministic
from .constraints import constraint_rank
from .residuals import FD_STEP

if TYPE_CHECKING:
    from .solver import Problem

Array = NDArray[np.float64]

#: A parameter whose 1σ from the observations alone exceeds this (metres or radians) is reported
#: as undetermined rather than given a value.
UNDETERMINED_SIGMA = 1.0


@dataclass
class Solution:
    """What a solve found: the vector, cameras, markers, covariance and per-observation residuals."""

    x: Array
    names: list[str]
    covariance: Array
    cameras: dict[str, ImageCamera]
    markers: dict[str, Array]
    marker_covariance: dict[str, Array]
    residuals_px: dict[str, list[Array]] = field(default_factory=dict)
    outliers: list[str] = field(default_factory=list)
    undetermined: list[str] = field(default_factory=list)
    variance_factor: float = 1.0
    iterations: int = 0
    #: photo id → 1σ of its lens distortion k1, for the photos whose k1 the solve refined.
    k1_sigma: dict[str, float] = field(default_factory=dict)


@deterministic
def solution_at(problem: Problem, x: Array, iterations: int = 0) -> Solution:
    """Covariance, residuals per observation, outliers and undetermined parameters at x."""
    layout = problem.layout
    J = problem.jacobian(x)
    r = problem.evaluate(x)
    # Hard rows (flush, aligned) are constraints: each independent one takes an unknown away
    # rather than adding an observation, so the redundancy is rows − unknowns + constraints. The
    # pulls toward the values before the solve are counted among the rows as they always were
    # (their residuals are ~0 in a final solve, so this count exceeds the observations' own
    # redundancy by the number of pulled unknowns; kept so that a project solves as before).
    hard = np.concatenate(problem.rows_hard).astype(int) if problem.rows_hard else np.zeros(0, int)
    soft = np.setdiff1d(np.arange(len(r)), hard)
    s2 = variance_factor(r[soft], layout.n - constraint_rank(J[hard]))
    cov = _inverse(J.T @ J) * s2
    # What the observations alone determine: without the pull toward the starting values
    # (the cameras' calibration priors, and the entered values' measurements, are observations too).
    data_rows = np.r_[np.arange(problem.n_data + len(problem.distances)), problem.rows_entered,
                      *[problem.rows_prior_cam[c] for c in problem.rows_prior_cam], hard].astype(int)
    Jd = J[data_rows]
    A = Jd.T @ Jd
    A = cast(Any, A).toarray() if sparse.issparse(A) else np.asarray(A)
    Js = J[data_rows[: len(data_rows) - len(hard)]]  # the ridge's scale: the observations' (not the stiff rows')
    As = Js.T @ Js
    ridge = 1e-12 * max(float(np.max(cast(Any, As).diagonal())), 1e-30)
    cov_data = _inverse(A + ridge * np.eye(layout.n))
    undetermined = [layout.model.names[j] for j in range(len(layout.model))
                    if not np.isfinite(cov_data[j, j]) or np.sqrt(max(cov_data[j, j], 0)) > UNDETERMINED_SIGMA]
    sigma = problem.sigma
    res: dict[str, list[Array]] = {"pins": [], "edges": [], "markers": []}
    outliers = []
    for i, p in enumerate(problem.pins):
        d = r[problem.rows_pin[i]] * sigma
        res["pins"].append(d)
        if np.linalg.norm(d) / sigma > OUTLIER_SIGMAS:
            outliers.append(f"pin {p.node}:{p.handle} in photo '{p.photo}' ({np.linalg.norm(d):.1f} px)")
    for i, e in enumerate(problem.edges):
        d = r[problem.rows_edge[i]] * sigma
        res["edges"].append(d)
        if np.max(np.abs(d)) / sigma > OUTLIER_SIGMAS:
            outliers.append(f"edge {e.node}:{e.edge} in photo '{e.photo}' ({np.max(np.abs(d)):.1f} px)")
    for i, m in enumerate(problem.marker_obs):
        d = r[problem.rows_marker[i]] * sigma
        res["markers"].append(d)
        if np.linalg.norm(d) / sigma > OUTLIER_SIGMAS:
            outliers.append(f"marker {m.marker} in photo '{m.photo}' ({np.linalg.norm(d):.1f} px)")
    cams, k1_sigma = {}, {}
    k1 = problem.camera_k1(x)
    for cid, (K, R, C) in problem.camera_matrices(x).items():
        old = problem.cameras[cid]
        cov_c = old.covariance
        blk = layout.cameras.get(cid)
        if blk is not None:
            cov_c = np.zeros((9, 9)) if old.covariance is None else np.asarray(old.covariance, float).copy()
            cal = slice(blk.start, blk.start + len(blk.calibration_index))
            cov_c[np.ix_(blk.calibration_index, blk.calibration_index)] = cov[cal, cal]
            if blk.k1_index is not None:
                k1_sigma[cid] = float(np.sqrt(max(cov[blk.k1_index, blk.k1_index], 0.0)))
        cams[cid] = ImageCamera(cid, K, R, np.asarray(C, float).copy(), old.width, old.height, covariance=cov_c,
                                k1=k1[cid])
    markers = problem.marker_positions(x)
    mcov = {k: cov[blk.slice, blk.slice] for k, blk in layout.markers.items()}
    return Solution(x, list(layout.model.names), cov, cams, {k: np.asarray(v).copy() for k, v in markers.items()},
                    mcov, res, outliers, undetermined, s2, iterations, k1_sigma)


def _inverse(A: Array | sparse.spmatrix) -> Array:
    """Inverse of a symmetric positive (semi-)definite normal matrix; ∞ where it is singular."""
    A = cast(Any, A).toarray() if sparse.issparse(A) else np.asarray(A)
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        cov = np.linalg.pinv(A)
        cov[np.diag_indices_from(cov)] = np.inf
        return cov


@deterministic
def handle_covariances(problem: Problem, x: Array, cov: Array) -> dict[str, tuple[Array, Array]]:
    """World position and 3×3 covariance of every handle, propagated from the parameters'.

    Returns 'node:handle' → (position (3,), covariance (3, 3)).
    """
    xm = problem.model_vector(x)
    T = problem.model.world_transforms(xm)
    H = problem.handle_positions(xm, T)
    G = np.zeros((problem.n_handles, 3, problem.layout.n))
    for j in problem.layout.model.indices:
        nodes, hrows = problem.moves[j]
        if not len(hrows):
            continue
        h = FD_STEP * max(1.0, abs(x[j]))
        xp = x.copy()
        xp[j] += h
        xmp = problem.model_vector(xp)
        Hp = problem.handle_positions(xmp, problem.model.world_transforms(xmp, only=nodes, cache=T), nodes, H.copy())
        G[hrows, :, j] = (Hp[hrows] - H[hrows]) / h
    out = {}
    for name in problem.prim_nodes:
        o = problem.h_offset[name]
        for k, hname in enumerate(problem.primitive_of(name).handle_names()):
            g = G[o + k]
            cols = np.flatnonzero(np.any(g != 0, axis=0))
            c = g[:, cols] @ cov[np.ix_(cols, cols)] @ g[:, cols].T if len(cols) else np.zeros((3, 3))
            out[f"{name}:{hname}"] = (H[o + k].copy(), c)
    return out
