"""The residuals of the model solver (paper §3.1, §3.2) and their Jacobian.

Observations are the user's marks: vertex pins (a handle of a node seen at a pixel in a photo)
and edge observations (the user's red edge: two pixels a model edge must pass through), and,
when re-calibrating, marker sightings and reference distances. Residuals are in pixels, whitened
by the click noise, then the priors: each free model parameter pulled toward its value before
the solve (a dimension entered from a measurement, FORMAT.md ``hold`` ``{"name", "sigma"}``: held
at its entered value by that measurement's 1σ instead, an observation like a pin), each
re-calibrated camera held by its calibration covariance (a camera group's shared intrinsics once, by
the group's prior: :mod:`.camera_blocks`), and last the hard rows of the flush and
aligned relations (:mod:`.constraints`: metres whitened by a micrometre, constraints rather than
observations). An ``equal`` relation is no row: its members share one unknown (``model_vector``).

Every projection goes through each photo's lens distortion (the division model of
vebuild/camera.py, :attr:`ImageCamera.lens`): a pin or a marker sighting is compared with the
distorted projection of its point; an edge observation's clicked points, as the lens put them, are
undistorted onto the pinhole image, where the model edge is a straight line, and their distance
from it is converted back to the photo's pixels by the undistortion's local scale across the line
(so that it is whitened by the same click noise as a pin). When re-calibrating, a photo's k1 may
be an unknown too, held by its prior (:class:`~vebuild.model.solver.ProblemOptions`).

The Jacobian is analytic for cameras (their k1 included) and markers; for a model parameter, the handles it moves are
differenced and chained through the analytic projection derivative, column by column, each
column re-evaluating only the observations that its parameter can move (the node's subtree), so
its cost grows with the number of observations, not with their square.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.calibration.lm import SPARSE_SOLVE_ABOVE
from vebuild.calibration.positions import ReferenceDistance  # ends: marker names or 'node:handle'
from vebuild.camera import ImageCamera, distortion_derivatives_each, project_each, skew_batch, so3_left_jacobian

from .camera_blocks import CameraBlocks
from .column_groups import column_groups
from .constraints import HARD_SIGMA_M
from .edge_distance import edge_distances
from .graph import Relation
from .layout import ParameterLayout
from .moved import MovePlan, apply_plan, move_plan
from .primitives import Primitive
from .relations import is_edge
from .relations import rows_of as relation_rows
from .scene import Model

if TYPE_CHECKING:
    from scipy import sparse

Array = NDArray[np.float64]
Index = NDArray[np.intp]

#: Step of the finite differences over a model parameter (relative above 1).
FD_STEP = 1e-6


@dataclass
class Pin:
    photo: str
    node: str
    handle: str
    uv: Array
    fixed: bool = True


@dataclass
class EdgeObservation:
    photo: str
    node: str
    edge: str
    points: Array  # (2, 2)


@dataclass
class MarkerObservation:
    photo: str
    marker: str
    uv: Array


class Residuals(CameraBlocks):
    """The residual vector and Jacobian of a :class:`~vebuild.model.solver.Problem`: its rows
    (pins, edges, marker sightings, distances, then the priors) and what each unknown moves.

    The problem sets up the unknowns (which model parameters are free, the layout of the vector,
    the observations it keeps, the priors) and then calls :meth:`_build_dependencies`.
    """

    model: Model
    layout: ParameterLayout
    cam_ids: list[str]
    cameras: dict[str, ImageCamera]
    sigma: float
    pins: list[Pin]
    edges: list[EdgeObservation]
    marker_obs: list[MarkerObservation]
    distances: list[ReferenceDistance]
    markers0: dict[str, Array]
    free_markers: list[str]
    x_model0: Array
    free_idx: NDArray[np.intp]
    owner: list[str]
    prior_sigma: Array
    _moving: list[str] | None  # the nodes a free parameter moves; None: all of them
    _T0: dict[str, Array]
    _H0: Array
    #: Equal relations (:class:`~vebuild.model.constraints.Ties`): xm[tie_dst] = xm[tie_src];
    #: column → the other nodes a shared unknown moves; member name → the unknown it shares.
    tie_src: NDArray[np.intp]
    tie_dst: NDArray[np.intp]
    also: dict[int, tuple[str, ...]]
    alias: dict[str, str]
    hard: list[Relation]  # the flush and aligned relations kept as hard rows
    _hard_J: Array | None = None  # their rows of the last Jacobian (whitened)

    def primitive_of(self, node: str) -> Primitive:
        """The primitive of node ``node`` (observations name only primitive nodes)."""
        prim = self.model.node(node).primitive
        if prim is None:
            raise ValueError(f"node '{node}' is a group: it has no handles or edges to observe")
        return prim

    # -- the vector's blocks -----------------------------------------------------------------
    def model_vector(self, x: Array) -> Array:
        """The whole model's parameter vector (free ones from x, the others as they were)."""
        xm = self.x_model0.copy()
        xm[self.free_idx] = x[self.layout.model.slice]
        xm[self.tie_dst] = xm[self.tie_src]  # equal relations: the members copy the shared unknown
        return xm

    def marker_positions(self, x: Array) -> dict[str, Array]:
        """Every marker's position at x (the fixed ones as calibrated)."""
        pos = dict(self.markers0)
        for k, blk in self.layout.markers.items():
            pos[k] = x[blk.slice]
        return pos

    # -- residuals ---------------------------------------------------------------------------
    def _build_dependencies(self) -> None:
        """Row layout, index arrays for vectorised evaluation, and what each parameter moves."""
        model = self.model
        self.prim_nodes = [n.name for n in model.nodes if n.primitive is not None]
        # Linear primitives' handles are one matrix product (A p); the others (a room) are asked.
        self._hmat = {n: self.primitive_of(n).handle_jacobian() for n in self.prim_nodes if self.primitive_of(n).LINEAR}
        self.h_offset: dict[str, int] = {}
        k = 0
        for name in self.prim_nodes:
            self.h_offset[name] = k
            k += len(self.primitive_of(name).handle_names())
        self.n_handles = k

        cam_index = {c: i for i, c in enumerate(self.cam_ids)}
        self.pin_row = np.array([self.handle_row(p.node, p.handle) for p in self.pins], dtype=int)
        self.pin_cam = np.array([cam_index[p.photo] for p in self.pins], dtype=int)
        self.pin_uv = np.array([p.uv for p in self.pins], float).reshape(-1, 2)
        ends = []
        for e in self.edges:
            names = {n: (a, b) for n, a, b in self.primitive_of(e.node).edges()}
            ends.append([self.handle_row(e.node, h) for h in names[e.edge]])
        self.edge_rows = np.array(ends, dtype=int).reshape(-1, 2)
        self.edge_cam = np.array([cam_index[e.photo] for e in self.edges], dtype=int)
        self.edge_pts = np.array([e.points for e in self.edges], float).reshape(-1, 2, 2)
        self.marker_names = sorted(self.markers0)
        m_index = {m: i for i, m in enumerate(self.marker_names)}
        self.mo_marker = np.array([m_index[m.marker] for m in self.marker_obs], dtype=int)
        self.mo_cam = np.array([cam_index[m.photo] for m in self.marker_obs], dtype=int)
        self.mo_uv = np.array([m.uv for m in self.marker_obs], float).reshape(-1, 2)
        # A distance end is a handle row (≥ 0) or a marker, coded −1 − marker index.
        self.dist_ends = np.array([[self.handle_row(*p.split(":", 1)) if ":" in p else -1 - m_index[p]
                                    for p in (d.a, d.b)] for d in self.distances], dtype=int).reshape(-1, 2)
        self.dist_value = np.array([d.distance for d in self.distances], float)
        self.dist_sigma = np.array([d.sigma for d in self.distances], float)

        rows = 0
        self.rows_pin = np.arange(rows, rows + 2 * len(self.pins)).reshape(-1, 2)
        rows += 2 * len(self.pins)
        self.rows_edge = np.arange(rows, rows + 2 * len(self.edges)).reshape(-1, 2)
        rows += 2 * len(self.edges)
        self.rows_marker = np.arange(rows, rows + 2 * len(self.marker_obs)).reshape(-1, 2)
        rows += 2 * len(self.marker_obs)
        self.rows_dist = np.arange(rows, rows + len(self.distances))
        rows += len(self.distances)
        self.n_data = 2 * (len(self.pins) + len(self.edges) + len(self.marker_obs))
        n_model = len(self.layout.model)
        self.rows_prior_model = np.arange(rows, rows + n_model)
        rows += n_model
        rows = self._prior_rows(rows)
        # Hard rows (flush, aligned) last: constraints, outside the robust loss and the observations.
        self.rows_hard: list[Index] = []
        for r in self.hard:
            n_rows = 4 if is_edge(model, r.a or "") else 3
            self.rows_hard.append(np.arange(rows, rows + n_rows))
            rows += n_rows
        self.m = rows
        self._entered_priors()
        # For each free model parameter: the nodes it moves and their handle rows.
        self.moves = []
        self.column_rows = []  # per model parameter: the pins, edges and distances it moves
        subtree_cache: dict[tuple[str, ...], tuple] = {}
        self.column_hard = []  # per model parameter: the hard relations it moves
        for j in range(n_model):
            owner = self.owner[j]
            key = (owner, *self.also.get(j, ()))
            if key not in subtree_cache:
                nodes = sorted(set().union(*(model.subtree(o) for o in key)), key=model.index.__getitem__)
                hrows = np.concatenate([self.handle_rows(n) for n in nodes] or [np.zeros(0, dtype=int)])
                subtree_cache[key] = (
                    (nodes, hrows),
                    (np.flatnonzero(np.isin(self.pin_row, hrows)),
                     np.flatnonzero(np.isin(self.edge_rows, hrows).any(axis=1)),
                     np.flatnonzero(np.isin(self.dist_ends, hrows).any(axis=1))),
                    [k for k, r in enumerate(self.hard) if set(r.nodes()) & set(nodes)],
                )
            self.moves.append(subtree_cache[key][0])
            self.column_rows.append(subtree_cache[key][1])
            self.column_hard.append(subtree_cache[key][2])
        self.column_groups = column_groups(self.layout.model.indices, self.moves, self.column_rows, self.column_hard)
        self._plans: dict[tuple[str, ...], MovePlan] = {}

    def move_plan(self, columns: Sequence[int]) -> MovePlan:
        """How a difference over the model parameters ``columns`` (one group) moves the model's
        transforms and handles (:mod:`.moved`)."""
        changed = sorted({n for j in columns for n in (self.owner[j], *self.also.get(j, ()))})
        key = tuple(changed)
        if key not in self._plans:
            moved = [n for j in columns for n in self.moves[j][0]]
            self._plans[key] = move_plan(self.model, changed, moved, self.handle_rows,
                                         {n for r in self.hard for n in r.nodes()})
        return self._plans[key]

    def handle_row(self, node: str, handle: str) -> int:
        """The row of ``node``'s handle ``handle`` in the stacked handles (:meth:`handle_positions`)."""
        return self.h_offset[node] + self.primitive_of(node).handle_names().index(handle)

    def handle_rows(self, node: str) -> Index:
        """The rows of ``node``'s handles in the stacked handles (none for a group)."""
        k = len(self.primitive_of(node).handle_names()) if node in self.h_offset else 0
        return np.arange(self.h_offset.get(node, 0), self.h_offset.get(node, 0) + k)

    def _difference_column(self, j: int, h: float, dHg: Array, Hp: Array, H: Array, M: Array,
                           Tp: Mapping[str, Array], xmp: Array, hard0: list[Array], MR_p: Any, Ks: Array, Rs: Array,
                           Cs: Array, lens_k: Array, put: Any) -> None:
        """Model parameter j's column from its group's difference (:func:`.column_groups.column_groups`): the
        handles j moves (and no other parameter of the group does) moved by ``dHg`` for a step h."""
        pin_sel, edge_sel, dist_sel = self.column_rows[j]
        dH = dHg / h
        for k in self.column_hard[j]:
            rel = self.hard[k]
            put(self.rows_hard[k], j, (relation_rows(rel, self.model, Tp, xmp) - hard0[k]) / h / HARD_SIGMA_M)
        if len(pin_sel):
            put(self.rows_pin[pin_sel], j, np.einsum("nij,nj->ni", MR_p[pin_sel], dH[self.pin_row[pin_sel]]))
        if len(edge_sel):
            a, b = self.edge_rows[edge_sel, 0], self.edge_rows[edge_sel, 1]
            r0 = self._edge_residuals(H[a], H[b], Ks, Rs, Cs, lens_k, edge_sel)
            r1 = self._edge_residuals(Hp[a], Hp[b], Ks, Rs, Cs, lens_k, edge_sel)
            put(self.rows_edge[edge_sel], j, (r1 - r0) / h)
        if len(dist_sel):
            e = self.dist_ends[dist_sel]
            d0 = np.linalg.norm(self._ends(e[:, 0], H, M) - self._ends(e[:, 1], H, M), axis=1)
            d1 = np.linalg.norm(self._ends(e[:, 0], Hp, M) - self._ends(e[:, 1], Hp, M), axis=1)
            put(self.rows_dist[dist_sel], j, (d1 - d0) / h / self.dist_sigma[dist_sel])

    def _entered_priors(self) -> None:
        """Where each free model parameter's prior is centred (``prior_model_at``: its value before
        the solve, or its entered value) and ``rows_entered``: the prior rows of the entered ones
        (σ > 0), whose 1σ replaces the pull's in ``prior_sigma``. They are observations: they
        determine a dimension no photo shows. Members of one ``equal`` group share an unknown: each
        entered member is a measurement of it, so their entries combine as independent Gaussian
        measurements do (the inverse-variance mean, 1σ = (Σ 1/σᵢ²)^-½), none overriding another."""
        model = self.model
        self.prior_model_at = np.array(self.x_model0[self.free_idx], float)
        self.prior_sigma = np.array(self.prior_sigma, float)
        index = {nm: j for j, nm in enumerate(self.layout.model.names)}
        entries: dict[int, list[tuple[float, float]]] = {}  # per unknown: (value, σ) of each entry
        for n in model.nodes:
            for e in n.entered:
                name = f"{n.name}.{e.name}"
                j = index.get(self.alias.get(name, name))  # a member of an equal group: its shared unknown
                if j is None or e.sigma <= 0 or e.value is None:
                    continue
                angle = self.layout.model.kinds[j] == "angle"
                value, sigma = (np.radians(e.value), np.radians(e.sigma)) if angle else (e.value, e.sigma)
                entries.setdefault(j, []).append((float(value), float(sigma)))
        for j, vs in entries.items():
            v, s = np.array(vs).T
            w = s ** -2.0
            # One entry: its own value and σ, exactly as entered.
            self.prior_model_at[j] = v[0] if len(vs) == 1 else float(w @ v / w.sum())
            self.prior_sigma[j] = s[0] if len(vs) == 1 else float(w.sum() ** -0.5)
        self.rows_entered = self.rows_prior_model[np.array(sorted(entries), dtype=int)]

    def set_pin_pixel(self, i: int, uv: ArrayLike) -> None:
        """Move pin i's observed pixel (the mouse, during a drag) without rebuilding the problem."""
        uv = np.asarray(uv, float)
        if uv.shape != (2,) or not np.all(np.isfinite(uv)):
            raise ValueError(f"pin {self.pins[i].node}:{self.pins[i].handle}: expected a finite pixel (u, v), got {uv}")
        self.pins[i].uv = uv
        self.pin_uv[i] = uv

    def handle_positions(self, xm: Array, T: Mapping[str, Array], nodes: Sequence[str] | None = None,
                         out: Array | None = None) -> Array:
        """World positions of every handle, stacked (n_handles, 3); only ``nodes`` are recomputed."""
        H = np.zeros((self.n_handles, 3)) if out is None else out
        for name in self.prim_nodes if nodes is None else [n for n in nodes if n in self.h_offset]:
            # Handles linear in a primitive's parameters: one matrix product per node.
            p = xm[self.model.slices[name][1]]
            hs = self._hmat[name] @ p if name in self._hmat else self.primitive_of(name).handles(p)
            o = self.h_offset[name]
            H[o : o + len(hs)] = hs @ T[name][:3, :3].T + T[name][:3, 3]
        return H

    def _camera_arrays(self, x: Array) -> tuple[Array, Array, Array, Array]:
        cams = self.camera_matrices(x)
        Ks = np.array([cams[c][0] for c in self.cam_ids]).reshape(-1, 3, 3)
        Rs = np.array([cams[c][1] for c in self.cam_ids]).reshape(-1, 3, 3)
        Cs = np.array([cams[c][2] for c in self.cam_ids]).reshape(-1, 3)
        lens = self.camera_lenses(x)
        return Ks, Rs, Cs, np.array([(lens[c].k1, lens[c].k2) for c in self.cam_ids], float).reshape(-1, 2)

    def _marker_array(self, x: Array) -> Array:
        pos = self.marker_positions(x)
        return np.array([pos[m] for m in self.marker_names], float).reshape(-1, 3)

    def _edge_residuals(self, Xa: Array, Xb: Array, Ks: Array, Rs: Array, Cs: Array, lens_k: Array,
                        idx: Index) -> Array:
        """Edge observations ``idx``: each clicked point's distance from the model edge's image
        (:func:`.edge_distance.edge_distances`), whitened by the click noise."""
        cam = self.edge_cam[idx]
        return edge_distances(Xa, Xb, Ks[cam], Rs[cam], Cs[cam], lens_k[cam], self.edge_pts[idx]) / self.sigma

    @staticmethod
    def _ends(ends: Index, H: Array, M: Array) -> Array:
        return np.where((ends >= 0)[:, None], H[np.maximum(ends, 0)], M[np.maximum(-1 - ends, 0)]) \
            if len(ends) else np.zeros((0, 3))

    def transforms(self, xm: Array) -> dict[str, Array]:
        """Every node's world transform for model vector xm (only the moving nodes recomputed)."""
        if self._moving is None:
            return self.model.world_transforms(xm)
        return self.model.world_transforms(xm, only=self._moving, cache=self._T0)

    def _posed(self, xm: Array) -> tuple[dict[str, Array], Array]:
        """World transforms and handle positions for model vector xm (only moving nodes recomputed)."""
        T = self.transforms(xm)
        if self._moving is None:
            return T, self.handle_positions(xm, T)
        return T, self.handle_positions(xm, T, self._moving, self._H0.copy())

    def evaluate(self, x: Array) -> Array:
        """The whitened residual vector."""
        xm = self.model_vector(x)
        T, H = self._posed(xm)
        Ks, Rs, Cs, lens_k = self._camera_arrays(x)
        M = self._marker_array(x)
        r = np.zeros(self.m)
        if len(self.pins):
            c = self.pin_cam
            uv = project_each(Ks[c], Rs[c], Cs[c], H[self.pin_row], lens_k[c])
            r[self.rows_pin.ravel()] = ((uv - self.pin_uv) / self.sigma).ravel()
        if len(self.edges):
            idx = np.arange(len(self.edges))
            r[self.rows_edge.ravel()] = self._edge_residuals(H[self.edge_rows[:, 0]], H[self.edge_rows[:, 1]],
                                                             Ks, Rs, Cs, lens_k, idx).ravel()
        if len(self.marker_obs):
            c = self.mo_cam
            uv = project_each(Ks[c], Rs[c], Cs[c], M[self.mo_marker], lens_k[c])
            r[self.rows_marker.ravel()] = ((uv - self.mo_uv) / self.sigma).ravel()
        if len(self.distances):
            pa = self._ends(self.dist_ends[:, 0], H, M)
            pb = self._ends(self.dist_ends[:, 1], H, M)
            r[self.rows_dist] = (np.linalg.norm(pa - pb, axis=1) - self.dist_value) / self.dist_sigma
        for rows, rel in zip(self.rows_hard, self.hard, strict=True):
            r[rows] = relation_rows(rel, self.model, T, xm) / HARD_SIGMA_M
        r[self.rows_prior_model] = (x[self.layout.model.slice] - self.prior_model_at) / self.prior_sigma
        self._camera_prior_residuals(x, r)
        return r

    def residuals(self, x: Array) -> Array:
        return self.evaluate(x)

    def jacobian(self, x: Array) -> Array | sparse.csr_matrix:
        """Sparse Jacobian: analytic for cameras and markers; for a model parameter, the handles it
        moves are differenced and chained through the analytic projection derivative."""
        from scipy import sparse  # imported at first use: docs/start-up.md

        xm = self.model_vector(x)
        T, H = self._posed(xm)
        Ks, Rs, Cs, lens_k = self._camera_arrays(x)
        M = self._marker_array(x)
        R_, C_, V_ = [], [], []
        # A drag has a handful of unknowns: a dense matrix is cheaper than sparse bookkeeping.
        n = self.layout.n
        dense = np.zeros((self.m, n)) if n <= SPARSE_SOLVE_ABOVE else None

        def put(rows: NDArray[Any], col: int | NDArray[Any], vals: NDArray[Any] | float) -> None:
            rows = np.asarray(rows).ravel()
            cols = np.broadcast_to(col, rows.shape).astype(int) if np.ndim(col) == 0 else np.asarray(col).ravel()
            if dense is not None:
                dense[rows, cols] = np.asarray(vals).ravel()
                return
            R_.append(rows)
            C_.append(cols)
            V_.append(np.asarray(vals).ravel())

        # d(residual)/d(world point) for pins and marker sightings: A R, A = ∂u/∂x_cam / σ, through
        # the lens: u = f s(|p|²) p + c with p = (x/z, y/z) and s the division model's scale
        # (camera.distortion_scale), so ∂u/∂p = f (s I + 2 s' p pᵀ); also ∂u/∂f = s p and
        # ∂u/∂k1 = f p ∂s/∂k1.
        def proj_parts(cam: Array, X: Array) -> tuple[Array, Array, Array, Array, Array]:
            xc = np.einsum("nij,nj->ni", Rs[cam], X - Cs[cam])
            f = Ks[cam, 0, 0]
            z = xc[:, 2]
            p = xc[:, :2] / z[:, None]
            lens = lens_k[cam]
            r2 = np.sum(p**2, axis=1)
            s, ds_dr2, ds_dk1, _ = distortion_derivatives_each(r2, lens)
            A = np.zeros((len(cam), 2, 3))
            A[:, 0, 0] = A[:, 1, 1] = f / z
            A[:, 0, 2] = -f * xc[:, 0] / z**2
            A[:, 1, 2] = -f * xc[:, 1] / z**2
            if np.any(lens != 0.0):  # through the lens: ∂u/∂p = f (s I + 2 s' p pᵀ); a pinhole's is f I
                D = s[:, None, None] * np.eye(2) + (2.0 * ds_dr2)[:, None, None] * p[:, :, None] * p[:, None, :]
                A = np.einsum("nij,njk->nik", D, A)
            A /= self.sigma
            return (A, np.einsum("nij,njk->nik", A, Rs[cam]), xc, s[:, None] * p,
                    (f * ds_dk1)[:, None] * p / self.sigma)

        none: tuple[Any, Any, Any, Any, Any] = (None, None, None, None, None)  # no such observations
        A_p, MR_p, xc_p, pd_p, dk_p = proj_parts(self.pin_cam, H[self.pin_row]) if len(self.pins) else none
        A_m, MR_m, xc_m, pd_m, dk_m = proj_parts(self.mo_cam, M[self.mo_marker]) if len(self.marker_obs) else none

        hard0 = [relation_rows(rel, self.model, T, xm) for rel in self.hard]
        for group in self.column_groups:
            cols = np.asarray(group, dtype=int)
            steps = FD_STEP * np.maximum(1.0, np.abs(x[cols]))
            xp = x.copy()
            xp[cols] += steps
            xmp = self.model_vector(xp)
            Tp, Hp = apply_plan(self.move_plan(group), self.model, xmp, T, H, self.handle_positions)
            dHg = Hp - H
            for j, h in zip(group, steps, strict=True):
                self._difference_column(j, float(h), dHg, Hp, H, M, Tp, xmp, hard0, MR_p, Ks, Rs, Cs, lens_k, put)

        if self.layout.cameras or self.layout.markers:
            for k, cid in enumerate(self.cam_ids):
                blk = self.layout.cameras.get(cid)
                if blk is None:
                    continue
                o, oc = blk.intrinsics_start, blk.pose_start
                w = x[oc : oc + 3]
                Jl = so3_left_jacobian(w)
                for rows_of, cam_of, A, MR, xc, pd, dk in (
                        (self.rows_pin, self.pin_cam, A_p, MR_p, xc_p, pd_p, dk_p),
                        (self.rows_marker, self.mo_cam, A_m, MR_m, xc_m, pd_m, dk_m)):
                    if A is None:
                        continue
                    sel = np.flatnonzero(cam_of == k)
                    if not len(sel):
                        continue
                    rows = rows_of[sel]  # (n, 2)
                    dw = -np.einsum("nij,njk->nik", A[sel], skew_batch(xc[sel])) @ Jl
                    for c in range(3):
                        put(rows, oc + c, dw[:, :, c])
                        put(rows, oc + 3 + c, -MR[sel][:, :, c])
                    if blk.intrinsics:  # u = f s p + c
                        put(rows, o, pd[sel] / self.sigma)
                        put(rows[:, 0], o + 1, np.full(len(sel), 1.0 / self.sigma))
                        put(rows[:, 1], o + 2, np.full(len(sel), 1.0 / self.sigma))
                    if blk.k1_index is not None:
                        put(rows, blk.k1_index, dk[sel])
                sel = np.flatnonzero(self.edge_cam == k)
                if len(sel):  # few edges: difference them
                    Xa, Xb = H[self.edge_rows[sel, 0]], H[self.edge_rows[sel, 1]]
                    x1 = x.copy()
                    r0 = self._edge_residuals(Xa, Xb, Ks, Rs, Cs, lens_k, sel)
                    for c in blk.columns:
                        x1[c] += FD_STEP
                        K1, R1, C1, lens_k1 = self._camera_arrays(x1)
                        put(self.rows_edge[sel], c,
                            (self._edge_residuals(Xa, Xb, K1, R1, C1, lens_k1, sel) - r0) / FD_STEP)
                        x1[c] = x[c]
            m_index = {m: i for i, m in enumerate(self.marker_names)}
            for name, mblk in self.layout.markers.items():
                mi = m_index[name]
                sel = np.flatnonzero(self.mo_marker == mi)
                for c in range(3):
                    if len(sel):
                        put(self.rows_marker[sel], mblk.start + c, MR_m[sel][:, :, c])
                if len(self.distances):
                    for end, sign in ((0, 1.0), (1, -1.0)):
                        dsel = np.flatnonzero(self.dist_ends[:, end] == -1 - mi)
                        if len(dsel):
                            e = self.dist_ends[dsel]
                            diff = self._ends(e[:, 0], H, M) - self._ends(e[:, 1], H, M)
                            u = diff / np.linalg.norm(diff, axis=1, keepdims=True) / self.dist_sigma[dsel, None]
                            for c in range(3):
                                put(self.rows_dist[dsel], mblk.start + c, sign * u[:, c])
        # Prior rows are linear: exact derivatives.
        put(self.rows_prior_model, self.layout.model.indices, 1.0 / self.prior_sigma)
        self._camera_prior_jacobian(put)
        J = dense if dense is not None else \
            sparse.coo_matrix((np.concatenate(V_), (np.concatenate(R_), np.concatenate(C_))), shape=(self.m, n)).tocsr()
        if self.hard:  # the hard rows' linearisation, for the steps' return onto the relations (Problem.clip)
            Jh: Any = J[np.concatenate(self.rows_hard)]
            self._hard_J = Jh.toarray() if sparse.issparse(Jh) else np.array(Jh)
        return J

    def describe_row(self, row: int) -> str:
        """What residual ``row`` measures: a pin, an edge, a marker sighting, a distance or a prior."""
        for rows, items, what in ((self.rows_pin, self.pins, lambda p: f"pin {p.node}:{p.handle} in photo "
                                   f"'{p.photo}'"),
                                  (self.rows_edge, self.edges, lambda e: f"edge {e.node}:{e.edge} in photo "
                                   f"'{e.photo}'"),
                                  (self.rows_marker, self.marker_obs, lambda m: f"marker '{m.marker}' in photo "
                                   f"'{m.photo}'")):
            if len(rows) and rows[0, 0] <= row <= rows[-1, 1]:
                return what(items[(row - int(rows[0, 0])) // 2])
        if len(self.rows_dist) and self.rows_dist[0] <= row <= self.rows_dist[-1]:
            d = self.distances[row - int(self.rows_dist[0])]
            return f"reference distance {d.a}–{d.b} ({d.distance:g} m)"
        if len(self.rows_prior_model) and self.rows_prior_model[0] <= row <= self.rows_prior_model[-1]:
            return f"the model parameter {self.layout.model.names[row - int(self.rows_prior_model[0])]}"
        prior = self.describe_prior_row(row)
        if prior is not None:
            return prior
        for hard_rows, rel in zip(self.rows_hard, self.hard, strict=True):
            if hard_rows[0] <= row <= hard_rows[-1]:
                return f"the relation {rel.label()}"
        return f"residual {row}"

    def check_finite(self, x: Array, when: str) -> None:
        """A :class:`~vebuild.errors.VebuildError` naming the first observation whose residual at
        ``x`` is not a finite number (a camera on a handle, a handle in a camera's plane, a size
        beyond floating point), rather than a solve that silently stops or a NumPy traceback."""
        from vebuild.errors import VebuildError

        with np.errstate(all="ignore"):
            bad = np.flatnonzero(~np.isfinite(self.residuals(x))) if np.all(np.isfinite(x)) else np.zeros(0, int)
        if not np.all(np.isfinite(x)):
            j = int(np.flatnonzero(~np.isfinite(x))[0])
            blk = self.layout.block_of(j)
            what = f"the model parameter {blk.names[j - blk.start]}" if blk.what == "model" else \
                f"the {blk.what} parameter {blk.names[j - blk.start]}"
            raise VebuildError(f"{what} is not a finite number {when}; check the values in the project's model")
        if len(bad):
            raise VebuildError(f"{self.describe_row(int(bad[0]))}: its residual is not a finite number {when} "
                               f"({len(bad)} such rows); the point lies in the camera's plane or at no finite place: "
                               "check that observation and the node's dimensions")

