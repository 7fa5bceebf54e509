"""The model solver (paper §3.1) and re-calibration (§3.2).

Observations are the user's marks: vertex pins (a handle of a node seen at a pixel in a photo)
and edge observations (the user's red edge: two pixels a model edge must pass through). Residuals
are in pixels, whitened by the click noise. The unknowns are the joints' degrees of freedom and the
primitives' parameters of the nodes being solved; with ``recalibrate`` also every camera's
rotation and position (and focal length if asked) and every marker's position, each camera held
by a prior equal to its calibration and covariance, as in :mod:`vebuild.calibration.positions`.

Vertex fixing (paper Figure 7) emerges from two ingredients rather than from a hand-made choice
of parameters: fixed vertices are pins that stay in the problem, and every parameter is pulled
gently toward its value before the solve, more gently for a joint's position than for a size.
With nothing fixed, the cheapest way to follow the mouse is to move the whole primitive; with a
vertex fixed, only a change of size or turn keeps it in place; directions that no observation
determines stay where they were.

The Jacobian is built by finite differences column by column, each column re-evaluating only the
observations that its parameter can move (the node's subtree, the camera's photo, the marker's
sightings), so its cost grows with the number of observations, not with their square.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.sparse.linalg import spsolve

from ..calibration.lsq import variance_factor
from ..calibration.positions import ReferenceDistance  # ends: marker names or 'node:handle'
from ..camera import ImageCamera, exp_so3, project_each, skew_batch, so3_left_jacobian
from ..determinism import deterministic
from .scene import Model

Array = NDArray[np.float64]

#: 1σ of the pull toward the value before a drag, per kind of parameter: metres for positions,
#: radians for angles, metres for sizes. A position is 10× freer than a size and, at a lever arm
#: of half a metre, 3× freer than a turn, so a lone drag moves the primitive rather than
#: stretching or turning it (paper Figure 7a); the pull also keeps each step of a drag local.
PRIOR_SIGMA = {"position": 1.0, "angle": 0.3, "size": 0.1}
#: In a final solve the pull only keeps undetermined directions in place: 10⁵ times weaker.
FINAL_PRIOR_SCALE = 1e5
OUTLIER_SIGMAS = 4.0
ROBUST_SCALE = 3.0
#: A parameter whose 1σ from the observations alone exceeds this (metres or radians) is reported
#: as undetermined rather than given a value.
UNDETERMINED_SIGMA = 1.0
FD_STEP = 1e-6
#: Above this many unknowns the normal equations are solved as a sparse system.
SPARSE_SOLVE_ABOVE = 400


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


def _prior_sigma(name: str) -> float:
    last = name.rsplit(".", 1)[-1]
    if last in ("yaw", "angle", "wx", "wy", "wz"):
        return PRIOR_SIGMA["angle"]
    if last in ("s", "t", "tx", "ty", "tz", "offset"):
        return PRIOR_SIGMA["position"]
    return PRIOR_SIGMA["size"]


class Problem:
    """One least-squares problem over a model (and optionally cameras and markers).

    Built once per drag or solve: everything that does not change between evaluations (which
    parameters are free, which observations each one moves, camera matrices) is set up here.
    """

    def __init__(
        self,
        model: Model,
        cameras: Mapping[str, ImageCamera],
        pins: Sequence[Pin] = (),
        edges: Sequence[EdgeObservation] = (),
        *,
        free_nodes: Sequence[str] | None = None,
        click_sigma_px: float = 1.0,
        prior_scale: float = 1.0,
        recalibrate: bool = False,
        refine_intrinsics: bool = False,
        markers: Mapping[str, Array] | None = None,
        fixed_markers: Sequence[str] = (),
        held: Collection[str] = (),
        marker_observations: Sequence[MarkerObservation] = (),
        distances: Sequence[ReferenceDistance] = (),
    ):
        self.model = model
        self.cam_ids = list(cameras)
        self.cameras = dict(cameras)
        self.sigma = click_sigma_px
        self.pins = [p for p in pins if p.photo in self.cameras]
        for p in self.pins:
            if np.shape(p.uv) != (2,) or not np.all(np.isfinite(p.uv)):
                raise ValueError(f"pin {p.node}:{p.handle} in photo '{p.photo}': expected a finite pixel (u, v), "
                                 f"got {p.uv}")
        self.edges = [e for e in edges if e.photo in self.cameras]
        self.x_model0 = model.vector()
        names = model.parameter_names()
        free = set(n.name for n in model.nodes if n.solve) if free_nodes is None else set(free_nodes)
        self.free_idx = []
        for n in model.nodes:
            if n.name in free:
                sq, sp = model.slices[n.name]
                names_n = list(n.joint.dof_names) + list(n.primitive.PARAMS if n.primitive is not None else ())
                idx = list(range(sq.start, sq.stop)) + list(range(sp.start, sp.stop))
                self.free_idx += [i for i, nm in zip(idx, names_n, strict=True)
                                  if nm not in n.hold and f"{n.name}.{nm}" not in held]
        self.free_idx = np.array(self.free_idx, dtype=int)
        lo, hi = model.bounds()
        self.names = [names[i] for i in self.free_idx]
        self.prior_sigma = np.array([_prior_sigma(n) for n in self.names]) * prior_scale
        self.lo, self.hi = lo[self.free_idx], hi[self.free_idx]
        # Node owning each model parameter (for the subtree it moves).
        owner = {}
        for n in model.nodes:
            sq, sp = model.slices[n.name]
            for i in list(range(sq.start, sq.stop)) + list(range(sp.start, sp.stop)):
                owner[i] = n.name
        self.owner = [owner[i] for i in self.free_idx]

        self.recalibrate = recalibrate
        self.refine_intrinsics = refine_intrinsics
        self.markers0 = {k: np.asarray(v, float) for k, v in (markers or {}).items()}
        self.marker_obs = [m for m in marker_observations if m.photo in self.cameras and m.marker in self.markers0]
        self.free_markers = [k for k in sorted(self.markers0) if k not in set(fixed_markers)] if recalibrate else []
        self.distances = list(distances)
        n_cam = (9 if refine_intrinsics else 6) if recalibrate else 0
        self.n_cam = n_cam
        self.n_model = len(self.free_idx)
        self.n = self.n_model + n_cam * len(self.cam_ids) + 3 * len(self.free_markers)
        self._prior_L = {}
        if recalibrate:
            for cid in self.cam_ids:
                cov = self.cameras[cid].covariance
                keep = ([0, 1, 2] if refine_intrinsics else []) + [3, 4, 5, 6, 7, 8]
                if cov is None:
                    self._prior_L[cid] = np.zeros((len(keep), len(keep)))
                    continue
                c = np.asarray(cov, float)[np.ix_(keep, keep)]
                w, V = np.linalg.eigh(0.5 * (c + c.T))
                self._prior_L[cid] = (V / np.sqrt(np.maximum(w, 1e-18))).T
        self._build_dependencies()
        # Only the subtrees of nodes with a free parameter move (during a drag, one object of the
        # scene): every other node's transform and handles are computed once, here.
        moving: set[str] = set()
        for name in set(self.owner):
            moving.update(model.subtree(name))
        self._moving = None if len(moving) == len(model.nodes) else sorted(moving, key=model.index.__getitem__)
        self._T0 = model.world_transforms(self.x_model0)
        self._H0 = self.handle_positions(self.x_model0, self._T0)

    # -- parameter blocks ------------------------------------------------------------------
    def x0(self) -> Array:
        parts = [self.x_model0[self.free_idx]]
        for cid in self.cam_ids if self.recalibrate else []:
            cam = self.cameras[cid]
            parts.append(np.r_[[0.0, 0.0, 0.0] if self.refine_intrinsics else [], 0.0, 0.0, 0.0, cam.C])
        parts += [self.markers0[k] for k in self.free_markers]
        return np.concatenate(parts) if parts else np.zeros(0)

    def bounds(self) -> tuple[Array, Array]:
        extra = self.n - self.n_model
        return np.r_[self.lo, np.full(extra, -np.inf)], np.r_[self.hi, np.full(extra, np.inf)]

    def model_vector(self, x: Array) -> Array:
        xm = self.x_model0.copy()
        xm[self.free_idx] = x[: self.n_model]
        return xm

    def camera_matrices(self, x: Array) -> dict[str, tuple[Array, Array, Array]]:
        out = {}
        for k, cid in enumerate(self.cam_ids):
            cam = self.cameras[cid]
            if not self.recalibrate:
                out[cid] = (cam.K, cam.R, cam.C)
                continue
            o = self.n_model + k * self.n_cam
            K = cam.K.copy()
            if self.refine_intrinsics:
                K[0, 0] = K[1, 1] = cam.K[0, 0] + x[o]
                K[0, 2] = cam.K[0, 2] + x[o + 1]
                K[1, 2] = cam.K[1, 2] + x[o + 2]
                o += 3
            out[cid] = (K, exp_so3(x[o : o + 3]) @ cam.R, x[o + 3 : o + 6])
        return out

    def marker_positions(self, x: Array) -> dict[str, Array]:
        pos = dict(self.markers0)
        o = self.n_model + self.n_cam * len(self.cam_ids)
        for i, k in enumerate(self.free_markers):
            pos[k] = x[o + 3 * i : o + 3 * i + 3]
        return pos

    # -- residuals ---------------------------------------------------------------------------
    def _build_dependencies(self) -> None:
        """Row layout, index arrays for vectorised evaluation, and what each parameter moves."""
        model = self.model
        self.prim_nodes = [n.name for n in model.nodes if n.primitive is not None]
        self._hmat = {n: model.node(n).primitive.handle_jacobian() for n in self.prim_nodes}
        self.h_offset: dict[str, int] = {}
        k = 0
        for name in self.prim_nodes:
            self.h_offset[name] = k
            k += len(model.node(name).primitive.handle_names())
        self.n_handles = k

        def hrow(node: str, handle: str) -> int:
            return self.h_offset[node] + model.node(node).primitive.handle_names().index(handle)

        cam_index = {c: i for i, c in enumerate(self.cam_ids)}
        self.pin_row = np.array([hrow(p.node, p.handle) for p in self.pins], dtype=int)
        self.pin_cam = np.array([cam_index[p.photo] for p in self.pins], dtype=int)
        self.pin_uv = np.array([p.uv for p in self.pins], float).reshape(-1, 2)
        ends = []
        for e in self.edges:
            names = {n: (a, b) for n, a, b in model.node(e.node).primitive.edges()}
            ends.append([hrow(e.node, h) for h in names[e.edge]])
        self.edge_rows = np.array(ends, dtype=int).reshape(-1, 2)
        self.edge_cam = np.array([cam_index[e.photo] for e in self.edges], dtype=int)
        self.edge_pts = np.array([e.points for e in self.edges], float).reshape(-1, 2, 2)
        self.marker_names = sorted(self.markers0)
        m_index = {m: i for i, m in enumerate(self.marker_names)}
        self.mo_marker = np.array([m_index[m.marker] for m in self.marker_obs], dtype=int)
        self.mo_cam = np.array([cam_index[m.photo] for m in self.marker_obs], dtype=int)
        self.mo_uv = np.array([m.uv for m in self.marker_obs], float).reshape(-1, 2)
        # A distance end is a handle row (≥ 0) or a marker, coded −1 − marker index.
        self.dist_ends = np.array([[hrow(*p.split(":", 1)) if ":" in p else -1 - m_index[p] for p in (d.a, d.b)]
                                   for d in self.distances], dtype=int).reshape(-1, 2)
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
        self.rows_prior_model = np.arange(rows, rows + self.n_model)
        rows += self.n_model
        self.rows_prior_cam = {}
        if self.recalibrate:
            for cid in self.cam_ids:
                self.rows_prior_cam[cid] = np.arange(rows, rows + self.n_cam)
                rows += self.n_cam
        self.m = rows
        # For each free model parameter: the nodes it moves and their handle rows.
        self.moves = []
        self.column_rows = []  # per model parameter: the pins, edges and distances it moves
        subtree_cache: dict[str, tuple] = {}
        for j in range(self.n_model):
            owner = self.owner[j]
            if owner not in subtree_cache:
                nodes = model.subtree(owner)
                hrows = np.concatenate(
                    [np.arange(self.h_offset[n], self.h_offset[n] + len(model.node(n).primitive.handle_names()))
                     for n in nodes if n in self.h_offset] or [np.zeros(0, dtype=int)])
                subtree_cache[owner] = (
                    (nodes, hrows),
                    (np.flatnonzero(np.isin(self.pin_row, hrows)),
                     np.flatnonzero(np.isin(self.edge_rows, hrows).any(axis=1)),
                     np.flatnonzero(np.isin(self.dist_ends, hrows).any(axis=1))),
                )
            self.moves.append(subtree_cache[owner][0])
            self.column_rows.append(subtree_cache[owner][1])

    def set_pin_pixel(self, i: int, uv: Array) -> None:
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
            # Handles are linear in a primitive's parameters: one matrix product per node.
            hs = self._hmat[name] @ xm[self.model.slices[name][1]]
            o = self.h_offset[name]
            H[o : o + len(hs)] = hs @ T[name][:3, :3].T + T[name][:3, 3]
        return H

    def _camera_arrays(self, x: Array) -> tuple[Array, Array, Array]:
        cams = self.camera_matrices(x)
        Ks = np.array([cams[c][0] for c in self.cam_ids]).reshape(-1, 3, 3)
        Rs = np.array([cams[c][1] for c in self.cam_ids]).reshape(-1, 3, 3)
        Cs = np.array([cams[c][2] for c in self.cam_ids]).reshape(-1, 3)
        return Ks, Rs, Cs

    def _marker_array(self, x: Array) -> Array:
        pos = self.marker_positions(x)
        return np.array([pos[m] for m in self.marker_names], float).reshape(-1, 3)

    def _edge_residuals(self, Xa: Array, Xb: Array, Ks: Array, Rs: Array, Cs: Array, idx: Array) -> Array:
        cam = self.edge_cam[idx]
        ha = np.einsum("nij,nj->ni", Ks[cam], np.einsum("nij,nj->ni", Rs[cam], Xa - Cs[cam]))
        hb = np.einsum("nij,nj->ni", Ks[cam], np.einsum("nij,nj->ni", Rs[cam], Xb - Cs[cam]))
        line = np.cross(ha, hb)
        line /= np.hypot(line[:, 0], line[:, 1])[:, None]
        pts = np.concatenate([self.edge_pts[idx], np.ones((len(idx), 2, 1))], axis=2)
        return np.einsum("nkj,nj->nk", pts, line) / self.sigma

    @staticmethod
    def _ends(ends: Array, H: Array, M: Array) -> Array:
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
        Ks, Rs, Cs = self._camera_arrays(x)
        M = self._marker_array(x)
        r = np.zeros(self.m)
        if len(self.pins):
            c = self.pin_cam
            uv = project_each(Ks[c], Rs[c], Cs[c], H[self.pin_row])
            r[self.rows_pin.ravel()] = ((uv - self.pin_uv) / self.sigma).ravel()
        if len(self.edges):
            idx = np.arange(len(self.edges))
            r[self.rows_edge.ravel()] = self._edge_residuals(H[self.edge_rows[:, 0]], H[self.edge_rows[:, 1]],
                                                             Ks, Rs, Cs, idx).ravel()
        if len(self.marker_obs):
            c = self.mo_cam
            uv = project_each(Ks[c], Rs[c], Cs[c], M[self.mo_marker])
            r[self.rows_marker.ravel()] = ((uv - self.mo_uv) / self.sigma).ravel()
        if len(self.distances):
            pa = self._ends(self.dist_ends[:, 0], H, M)
            pb = self._ends(self.dist_ends[:, 1], H, M)
            r[self.rows_dist] = (np.linalg.norm(pa - pb, axis=1) - self.dist_value) / self.dist_sigma
        r[self.rows_prior_model] = (x[: self.n_model] - self.x_model0[self.free_idx]) / self.prior_sigma
        for k, cid in enumerate(self.cam_ids if self.recalibrate else []):
            o = self.n_model + k * self.n_cam
            d = x[o : o + self.n_cam].copy()
            d[-3:] -= self.cameras[cid].C
            r[self.rows_prior_cam[cid]] = self._prior_L[cid] @ d
        return r

    def residuals(self, x: Array) -> Array:
        return self.evaluate(x)

    def jacobian(self, x: Array) -> Array | sparse.csr_matrix:
        """Sparse Jacobian: analytic for cameras and markers; for a model parameter, the handles it
        moves are differenced and chained through the analytic projection derivative."""
        xm = self.model_vector(x)
        T, H = self._posed(xm)
        Ks, Rs, Cs = self._camera_arrays(x)
        M = self._marker_array(x)
        R_, C_, V_ = [], [], []
        # A drag has a handful of unknowns: a dense matrix is cheaper than sparse bookkeeping.
        dense = np.zeros((self.m, self.n)) if self.n <= SPARSE_SOLVE_ABOVE else None

        def put(rows: Array, col: int | Array, vals: Array) -> None:
            rows = np.asarray(rows).ravel()
            cols = np.broadcast_to(col, rows.shape).astype(int) if np.ndim(col) == 0 else np.asarray(col).ravel()
            if dense is not None:
                dense[rows, cols] = np.asarray(vals).ravel()
                return
            R_.append(rows)
            C_.append(cols)
            V_.append(np.asarray(vals).ravel())

        # d(residual)/d(world point) for pins and marker sightings: A R, A = ∂π/∂x_cam / σ.
        def proj_parts(cam: Array, X: Array) -> tuple[Array, Array, Array]:
            xc = np.einsum("nij,nj->ni", Rs[cam], X - Cs[cam])
            f = Ks[cam, 0, 0]
            z = xc[:, 2]
            A = np.zeros((len(cam), 2, 3))
            A[:, 0, 0] = A[:, 1, 1] = f / z
            A[:, 0, 2] = -f * xc[:, 0] / z**2
            A[:, 1, 2] = -f * xc[:, 1] / z**2
            A /= self.sigma
            return A, np.einsum("nij,njk->nik", A, Rs[cam]), xc

        A_p, MR_p, xc_p = proj_parts(self.pin_cam, H[self.pin_row]) if len(self.pins) else (None,) * 3
        A_m, MR_m, xc_m = proj_parts(self.mo_cam, M[self.mo_marker]) if len(self.marker_obs) else (None,) * 3

        for j in range(self.n_model):
            nodes, hrows = self.moves[j]
            h = FD_STEP * max(1.0, abs(x[j]))
            xp = x.copy()
            xp[j] += h
            xmp = self.model_vector(xp)
            Tp = self.model.world_transforms(xmp, only=nodes, cache=T)
            Hp = self.handle_positions(xmp, Tp, nodes, H.copy())
            dH = (Hp - H) / h
            pin_sel, edge_sel, dist_sel = self.column_rows[j]
            if len(pin_sel):
                put(self.rows_pin[pin_sel], j, np.einsum("nij,nj->ni", MR_p[pin_sel], dH[self.pin_row[pin_sel]]))
            if len(edge_sel):
                a, b = self.edge_rows[edge_sel, 0], self.edge_rows[edge_sel, 1]
                r0 = self._edge_residuals(H[a], H[b], Ks, Rs, Cs, edge_sel)
                r1 = self._edge_residuals(Hp[a], Hp[b], Ks, Rs, Cs, edge_sel)
                put(self.rows_edge[edge_sel], j, (r1 - r0) / h)
            if len(dist_sel):
                e = self.dist_ends[dist_sel]
                d0 = np.linalg.norm(self._ends(e[:, 0], H, M) - self._ends(e[:, 1], H, M), axis=1)
                d1 = np.linalg.norm(self._ends(e[:, 0], Hp, M) - self._ends(e[:, 1], Hp, M), axis=1)
                put(self.rows_dist[dist_sel], j, (d1 - d0) / h / self.dist_sigma[dist_sel])

        if self.recalibrate:
            for k in range(len(self.cam_ids)):
                o = self.n_model + k * self.n_cam
                oc = o + (3 if self.refine_intrinsics else 0)
                w = x[oc : oc + 3]
                Jl = so3_left_jacobian(w)
                for rows_of, cam_of, A, MR, xc in ((self.rows_pin, self.pin_cam, A_p, MR_p, xc_p),
                                                   (self.rows_marker, self.mo_cam, A_m, MR_m, xc_m)):
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
                    if self.refine_intrinsics:  # u = f x/z + cx, v = f y/z + cy
                        put(rows, o, xc[sel, :2] / xc[sel, 2:3] / self.sigma)
                        put(rows[:, 0], o + 1, np.full(len(sel), 1.0 / self.sigma))
                        put(rows[:, 1], o + 2, np.full(len(sel), 1.0 / self.sigma))
                sel = np.flatnonzero(self.edge_cam == k)
                if len(sel):  # few edges: difference them
                    Xa, Xb = H[self.edge_rows[sel, 0]], H[self.edge_rows[sel, 1]]
                    x1 = x.copy()
                    r0 = self._edge_residuals(Xa, Xb, Ks, Rs, Cs, sel)
                    for c in range(o, o + self.n_cam):
                        x1[c] += FD_STEP
                        K1, R1, C1 = self._camera_arrays(x1)
                        put(self.rows_edge[sel], c, (self._edge_residuals(Xa, Xb, K1, R1, C1, sel) - r0) / FD_STEP)
                        x1[c] = x[c]
            om = self.n_model + self.n_cam * len(self.cam_ids)
            m_index = {m: i for i, m in enumerate(self.marker_names)}
            for i, name in enumerate(self.free_markers):
                mi = m_index[name]
                sel = np.flatnonzero(self.mo_marker == mi)
                for c in range(3):
                    if len(sel):
                        put(self.rows_marker[sel], om + 3 * i + c, MR_m[sel][:, :, c])
                if len(self.distances):
                    for end, sign in ((0, 1.0), (1, -1.0)):
                        dsel = np.flatnonzero(self.dist_ends[:, end] == -1 - mi)
                        if len(dsel):
                            e = self.dist_ends[dsel]
                            diff = self._ends(e[:, 0], H, M) - self._ends(e[:, 1], H, M)
                            u = diff / np.linalg.norm(diff, axis=1, keepdims=True) / self.dist_sigma[dsel, None]
                            for c in range(3):
                                put(self.rows_dist[dsel], om + 3 * i + c, sign * u[:, c])
        # Prior rows are linear: exact derivatives.
        put(self.rows_prior_model, np.arange(self.n_model), 1.0 / self.prior_sigma)
        for k, cid in enumerate(self.cam_ids if self.recalibrate else []):
            o = self.n_model + k * self.n_cam
            rr, cc = np.meshgrid(self.rows_prior_cam[cid], np.arange(o, o + self.n_cam), indexing="ij")
            put(rr, cc, self._prior_L[cid])
        if dense is not None:
            return dense
        J = sparse.coo_matrix((np.concatenate(V_), (np.concatenate(R_), np.concatenate(C_))), shape=(self.m, self.n))
        return J.tocsr()

    # -- solving -----------------------------------------------------------------------------
    @deterministic
    def solve(self, x0: Array | None = None, robust: bool = False, max_iterations: int = 100,
              tol: float = 1e-10, damping: float = 1e-4) -> LMResult:
        """Bounded Levenberg–Marquardt from x0 (default: the model's values).

        The normal equations JᵀJ are solved directly (sparse when large); a robust fit uses the
        soft-L1 loss on the observation rows (not on the priors).
        """
        x0 = self.x0() if x0 is None else x0
        lo, hi = self.bounds()
        # A robust fit reweights from the first iteration, so that a wrong mark is discounted
        # before it can drag the model (or the cameras) toward it.
        robust_rows = self.n_data + len(self.distances) if robust else 0
        return levenberg_marquardt(self.residuals, self.jacobian, np.clip(x0, lo, hi), lo, hi, max_iterations,
                                   tol=tol, damping=damping, robust_rows=robust_rows)

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
            return f"the model parameter {self.names[row - int(self.rows_prior_model[0])]}"
        for cid, rows in self.rows_prior_cam.items():
            if rows[0] <= row <= rows[-1]:
                return f"the calibration of photo '{cid}'"
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
            what = f"the model parameter {self.names[j]}" if j < self.n_model else "a camera or marker parameter"
            raise VebuildError(f"{what} is not a finite number {when}; check the values in the project's model")
        if len(bad):
            raise VebuildError(f"{self.describe_row(int(bad[0]))}: its residual is not a finite number {when} "
                               f"({len(bad)} such rows); the point lies in the camera's plane or at no finite place: "
                               "check that observation and the node's dimensions")

    @deterministic
    def solution(self, x: Array, iterations: int = 0) -> Solution:
        """Covariance, residuals per observation, outliers and undetermined parameters at x."""
        J = self.jacobian(x)
        r = self.evaluate(x)
        s2 = variance_factor(r, self.n)
        cov = _inverse(J.T @ J) * s2
        # What the observations alone determine: without the pull toward the starting values
        # (the cameras' calibration priors are observations too).
        data_rows = np.r_[np.arange(self.n_data + len(self.distances)),
                          *[self.rows_prior_cam[c] for c in self.rows_prior_cam]].astype(int)
        Jd = J[data_rows]
        A = Jd.T @ Jd
        A = A.toarray() if sparse.issparse(A) else np.asarray(A)
        ridge = 1e-12 * max(float(np.max(np.diag(A))), 1e-30)
        cov_data = _inverse(A + ridge * np.eye(self.n))
        undetermined = [self.names[j] for j in range(self.n_model)
                        if not np.isfinite(cov_data[j, j]) or np.sqrt(max(cov_data[j, j], 0)) > UNDETERMINED_SIGMA]
        res: dict[str, list[Array]] = {"pins": [], "edges": [], "markers": []}
        outliers = []
        for i, p in enumerate(self.pins):
            d = r[self.rows_pin[i]] * self.sigma
            res["pins"].append(d)
            if np.linalg.norm(d) / self.sigma > OUTLIER_SIGMAS:
                outliers.append(f"pin {p.node}:{p.handle} in photo '{p.photo}' ({np.linalg.norm(d):.1f} px)")
        for i, e in enumerate(self.edges):
            d = r[self.rows_edge[i]] * self.sigma
            res["edges"].append(d)
            if np.max(np.abs(d)) / self.sigma > OUTLIER_SIGMAS:
                outliers.append(f"edge {e.node}:{e.edge} in photo '{e.photo}' ({np.max(np.abs(d)):.1f} px)")
        for i, m in enumerate(self.marker_obs):
            d = r[self.rows_marker[i]] * self.sigma
            res["markers"].append(d)
            if np.linalg.norm(d) / self.sigma > OUTLIER_SIGMAS:
                outliers.append(f"marker {m.marker} in photo '{m.photo}' ({np.linalg.norm(d):.1f} px)")
        cams = {}
        for k, (cid, (K, R, C)) in enumerate(self.camera_matrices(x).items()):
            old = self.cameras[cid]
            cov_c = old.covariance
            if self.recalibrate:
                o = self.n_model + k * self.n_cam
                blk = cov[o : o + self.n_cam, o : o + self.n_cam]
                cov_c = np.zeros((9, 9)) if old.covariance is None else np.asarray(old.covariance, float).copy()
                keep = ([0, 1, 2] if self.refine_intrinsics else []) + [3, 4, 5, 6, 7, 8]
                cov_c[np.ix_(keep, keep)] = blk
            cams[cid] = ImageCamera(cid, K, R, np.asarray(C, float).copy(), old.width, old.height, covariance=cov_c)
        markers = self.marker_positions(x)
        mcov = {}
        o = self.n_model + self.n_cam * len(self.cam_ids)
        for i, k in enumerate(self.free_markers):
            mcov[k] = cov[o + 3 * i : o + 3 * i + 3, o + 3 * i : o + 3 * i + 3]
        return Solution(x, self.names, cov, cams, {k: np.asarray(v).copy() for k, v in markers.items()}, mcov,
                        res, outliers, undetermined, s2, iterations)


@dataclass
class LMResult:
    x: Array
    cost: float
    iterations: int
    converged: bool
    residuals: Array  # r(x) at the solution, whitened

    @property
    def nfev(self) -> int:  # the name scipy uses, kept for callers that report it
        return self.iterations


@deterministic
def levenberg_marquardt(fun, jac, x0: Array, lo: Array, hi: Array, max_iterations: int = 100, *,
                        robust_rows: int = 0, robust_scale: float = ROBUST_SCALE, tol: float = 1e-10,
                        damping: float = 1e-4) -> LMResult:
    """Minimise ½‖r(x)‖² (soft-L1 on the first ``robust_rows`` rows if given) within [lo, hi].

    Marquardt's scaled damping, steps projected onto the bounds (sizes stay positive, joints stay
    within their limits), damping raised until a step lowers the cost. The robust loss is handled
    by iteratively reweighted least squares: row i is weighted by ρ'(rᵢ²/c²)^½.
    """
    x = np.clip(np.asarray(x0, float), lo, hi)

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
                    step = -spsolve((A + sparse.diags(lam * d)).tocsc(), g)
                    if not np.all(np.isfinite(step)):
                        raise np.linalg.LinAlgError
                else:
                    step = -np.linalg.solve(A + lam * np.diag(d), g)
            except (np.linalg.LinAlgError, RuntimeError):
                lam *= 10.0
                continue
            x_new = np.clip(x + step, lo, hi)
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


def _inverse(A: Array | sparse.spmatrix) -> Array:
    """Inverse of a symmetric positive (semi-)definite normal matrix; ∞ where it is singular."""
    A = A.toarray() if sparse.issparse(A) else np.asarray(A)
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
    G = np.zeros((problem.n_handles, 3, problem.n))
    for j in range(problem.n_model):
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
        for k, hname in enumerate(problem.model.node(name).primitive.handle_names()):
            g = G[o + k]
            cols = np.flatnonzero(np.any(g != 0, axis=0))
            c = g[:, cols] @ cov[np.ix_(cols, cols)] @ g[:, cols].T if len(cols) else np.zeros((3, 3))
            out[f"{name}:{hname}"] = (H[o + k].copy(), c)
    return out
