"""What a model solve found (paper §3.1, §3.2): covariance, residuals per observation, outliers,
undetermined parameters, the re-calibrated cameras and markers, and the handles' covariances.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from vebuild.calibration.lsq import variance_factor
from vebuild.camera import ImageCamera, Lens
from vebuild.constants import OUTLIER_SIGMAS
from vebuild.determinism import deterministic

from .constraints import constraint_rank
from .inverse import inverse_by_cameras as _inverse_by_cameras
from .inverse import outside_cameras_inverse as _outside_cameras_inverse
from .moved import apply_plan
from .residuals import FD_STEP
from .solver import Problem

Array = NDArray[np.float64]

#: A position or size whose 1σ from the observations alone exceeds this share of the scene's extent
#: (the diagonal of the box around every handle of the model) is undetermined, not measured: its
#: 95 % interval would span a tenth of the scene and more. Relative, so that the rule holds for a
#: cupboard as for a hall and for a project in relative units. A wall whose far end one photo sees
#: at a grazing angle, solving to 6.1 ± 0.85 m in a 6.6 m scene (13 %), is undetermined; the
#: example room's least determined length (± 1.0 cm) is 0.14 % of its 7.2 m extent
#: (tests/test_determination.py).
UNDETERMINED_SHARE_OF_SCENE = 0.05
#: A size whose 1σ exceeds this share of its value is undetermined whatever the scene's size: its
#: 95 % interval reaches zero (the photos do not show that it has a size at all).
UNDETERMINED_SHARE_OF_VALUE = 0.5
#: An angle whose 1σ exceeds this (radians, 11.5°) is undetermined: its 95 % interval spans ±22°,
#: a turn no one would call measured. Angles have no scale to be relative to.
UNDETERMINED_ANGLE_RAD = 0.2
#: The extent taken for a model with fewer than two distinct handles (metres).
LEAST_SCENE_EXTENT = 1e-3


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
    #: The model parameters that only an entered value (a ``hold`` with σ > 0) determines: without
    #: the entered values they would be undetermined (FORMAT.md ``determined_by``).
    prior_only: list[str] = field(default_factory=list)
    #: The covariance of the model parameters from the observations alone (the pins, edges,
    #: markers, distances and camera priors, without entered values or the pull toward the start),
    #: slightly regularised so that it is finite: its columns give the directions no photo fixes.
    covariance_observed: Array | None = None
    #: The diagonal of the box around every handle of the solved model (metres).
    scene_extent: float = 1.0


@deterministic
def solution_at(problem: Problem, x: Array, iterations: int = 0) -> Solution:
    """Covariance, residuals per observation, outliers and undetermined parameters at x."""
    layout = problem.layout
    J = problem.jacobian(x)
    r = problem.evaluate(x)
    # The a-posteriori variance factor of the clicks (pins, edges, marker sightings): their χ²
    # over their redundancy, Σ (1 − h_ii) over their rows, h the hat matrix J (JᵀJ)⁻¹ Jᵀ (the
    # redundancy numbers; one step of variance-component estimation). The weak pull toward the
    # values before the solve takes no redundancy from them (counted as rows, it added one per
    # pulled unknown and under-stated σ0²), each independent hard row (flush, aligned) takes one
    # unknown's worth. Where the clicks fit worse than the stated click noise (σ0² > 1) their
    # weight is divided by σ0²; the measurements with their own σ (distances, the cameras'
    # calibration priors, entered values) keep theirs.
    hard = np.concatenate(problem.rows_hard).astype(int) if problem.rows_hard else np.zeros(0, int)
    observed = np.r_[np.arange(problem.n_data + len(problem.distances)),
                     *[problem.rows_prior_cam[c] for c in problem.rows_prior_cam],
                     *[problem.rows_prior_group[g] for g in problem.rows_prior_group]].astype(int)
    measured = np.r_[observed, problem.rows_entered].astype(int)  # the entered values are measurements
    clicks = np.arange(problem.n_data)
    camera_slices = [blk.slice for blk in layout.cameras.values()]
    unit = _inverse_by_cameras(J.T @ J, camera_slices)
    fitted = _leverage(J, unit, clicks) if np.all(np.isfinite(unit)) else \
        min(len(clicks), layout.n - constraint_rank(J[hard]))  # singular: the unknowns' count
    s2 = variance_factor(r[clicks], fitted)
    cov = unit
    if s2 > 1.0:
        Jw = _scaled_rows(J, clicks, 1.0 / s2)
        cov = _inverse_by_cameras(Jw.T @ Jw, camera_slices)
    # What the observations alone determine: without the pull toward the starting values
    # (the cameras' calibration priors are observations too, and the relations' hard rows hold);
    # then again with the entered values' measurements, to tell a parameter only an entered value
    # determines.
    cov_obs = _data_covariance(J, observed, hard, layout.n, camera_slices)
    extent = scene_extent(problem, x)
    names, kinds = layout.model.names, layout.model.kinds
    xmodel = x[layout.model.slice]

    def undetermined_in(c: Array) -> list[str]:
        return [names[j] for j in range(len(layout.model))
                if not determined(float(c[j, j]), float(xmodel[j]), kinds[j], extent)]

    # The entered values only add measurements: their normal matrix is the observations' plus a
    # positive one, so no variance is larger with them, and what the observations alone determine
    # stays determined. Their covariance (one more inverse: 0.14 s for the house, outside the
    # cameras) is only needed where the observations leave something undetermined.
    undetermined = undetermined_in(cov_obs)
    prior_only: list[str] = []
    if len(problem.rows_entered) and undetermined:
        alone = undetermined
        undetermined = undetermined_in(_data_covariance(J, measured, hard, layout.n, camera_slices))
        prior_only = [nm for nm in alone if nm not in undetermined]
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
            idx, cols = blk.camera_columns()  # a group's photo: its group's intrinsics and its own pose
            cov_c[np.ix_(idx, idx)] = cov[np.ix_(cols, cols)]
            if blk.k1_index is not None:
                k1_sigma[cid] = float(np.sqrt(max(cov[blk.k1_index, blk.k1_index], 0.0)))
        cams[cid] = ImageCamera(cid, K, R, np.asarray(C, float).copy(), old.width, old.height, covariance=cov_c,
                                lens=Lens(k1[cid], old.lens.k2))
    markers = problem.marker_positions(x)
    mcov = {k: cov[blk.slice, blk.slice] for k, blk in layout.markers.items()}
    n_model = len(layout.model)
    return Solution(x, list(layout.model.names), cov, cams, {k: np.asarray(v).copy() for k, v in markers.items()},
                    mcov, res, outliers, undetermined, s2, iterations, k1_sigma, prior_only,
                    cov_obs[:n_model, :n_model], extent)


def determined(variance: float, value: float, kind: str, extent: float) -> bool:
    """Whether a parameter with this variance from the observations (its value, its kind in
    DOF_KINDS, the scene's extent in metres) is measured rather than undetermined: the rule of
    UNDETERMINED_SHARE_OF_SCENE, UNDETERMINED_SHARE_OF_VALUE and UNDETERMINED_ANGLE_RAD."""
    if not np.isfinite(variance):
        return False
    s = float(np.sqrt(max(variance, 0.0)))
    if kind == "angle":
        return s <= UNDETERMINED_ANGLE_RAD
    if s > UNDETERMINED_SHARE_OF_SCENE * extent:
        return False
    return kind != "size" or s <= UNDETERMINED_SHARE_OF_VALUE * abs(value)


def scene_extent(problem: Problem, x: Array) -> float:
    """The diagonal (metres) of the axis-aligned box around every handle of the model at x."""
    xm = problem.model_vector(x)
    H = problem.handle_positions(xm, problem.model.world_transforms(xm))
    if len(H) < 2:
        return LEAST_SCENE_EXTENT
    return max(float(np.linalg.norm(np.ptp(H, axis=0))), LEAST_SCENE_EXTENT)


def _scaled_rows(J: Array | sparse.spmatrix, rows: NDArray[np.intp], weight: float) -> Array | sparse.spmatrix:
    """J with ``rows`` multiplied by √weight (their weight in JᵀJ by ``weight``)."""
    w = np.ones(J.shape[0])
    w[rows] = np.sqrt(weight)
    return sparse.diags(w) @ J if sparse.issparse(J) else w[:, None] * J


def _leverage(J: Array | sparse.spmatrix, unit: Array, rows: NDArray[np.intp]) -> float:
    """Σ h_ii over ``rows``: the unknowns' worth those rows fit (h the hat matrix J (JᵀJ)⁻¹ Jᵀ of
    the whitened rows, ``unit`` = (JᵀJ)⁻¹, finite), as trace((JᵀJ)⁻¹ J_rowsᵀ J_rows): the rows'
    normal matrix, no m × n product."""
    Jr = J[rows]
    A = Jr.T @ Jr
    h = cast(Any, A).multiply(unit).sum() if sparse.issparse(A) else np.einsum("ij,ij->", np.asarray(A), unit)
    return float(h)


def _data_covariance(J: Array | sparse.spmatrix, rows: Array, hard: Array, n: int,
                     cameras: Sequence[slice] = ()) -> Array:
    """(J_rowsᵀ J_rows + J_hardᵀ J_hard + a tiny ridge)⁻¹: the covariance the rows alone give (unit
    weights) with the relations' hard rows holding. The ridge's scale is the rows' own, not the
    stiff hard rows'. Only the block of the unknowns outside ``cameras`` (each camera's slice of
    the unknowns) is returned, in their order: the model's and the markers'
    (:func:`_outside_cameras_inverse`)."""
    Js = J[rows]
    As = Js.T @ Js
    As = cast(Any, As).toarray() if sparse.issparse(As) else np.asarray(As)
    ridge = 1e-12 * max(float(np.max(np.diag(As))) if As.size else 0.0, 1e-30)
    A = As
    if len(hard):
        Jh = J[hard]
        Ah = Jh.T @ Jh
        A = As + (cast(Any, Ah).toarray() if sparse.issparse(Ah) else np.asarray(Ah))
    return _outside_cameras_inverse(A + ridge * np.eye(n), cameras)


def handle_gradients(problem: Problem, x: Array) -> tuple[Array, Array]:
    """World positions of every handle at x, stacked (n_handles, 3), and their derivatives with
    respect to every unknown, (n_handles, 3, n) (zero for the cameras')."""
    xm = problem.model_vector(x)
    T = problem.model.world_transforms(xm)
    H = problem.handle_positions(xm, T)
    G = np.zeros((problem.n_handles, 3, problem.layout.n))
    for j in problem.layout.model.indices:
        hrows = problem.moves[j][1]
        if not len(hrows):
            continue
        h = FD_STEP * max(1.0, abs(x[j]))
        xp = x.copy()
        xp[j] += h
        _, Hp = apply_plan(problem.move_plan([j]), problem.model, problem.model_vector(xp), T, H,
                           problem.handle_positions)
        G[hrows, :, j] = (Hp[hrows] - H[hrows]) / h
    return H, G


@deterministic
def handle_covariances(problem: Problem, x: Array, cov: Array) -> dict[str, tuple[Array, Array]]:
    """World position and 3×3 covariance of every handle, propagated from the parameters'.

    Returns 'node:handle' → (position (3,), covariance (3, 3)).
    """
    H, G = handle_gradients(problem, x)
    out = {}
    for name in problem.prim_nodes:
        o = problem.h_offset[name]
        for k, hname in enumerate(problem.primitive_of(name).handle_names()):
            g = G[o + k]
            cols = np.flatnonzero(np.any(g != 0, axis=0))
            c = g[:, cols] @ cov[np.ix_(cols, cols)] @ g[:, cols].T if len(cols) else np.zeros((3, 3))
            out[f"{name}:{hname}"] = (H[o + k].copy(), c)
    return out
