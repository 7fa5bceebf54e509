"""Laser-scan points as observations of the model's flat faces: point-to-face residuals.

A :class:`SurfaceObservation` says that world points (a registered scan's, assigned to a face by
:func:`vebuild.analysis.scans.surface_observations`) lie on the face ``face`` of ``node``. Its
residual per point is the signed distance from the point to the face's plane, whitened by the
points' 1σ, then robustly weighted: the soft-L1 loss (as the clicks', scale ROBUST_SCALE σ) put in
the residual itself, ``r' = sign(r) √(2c²(√(1 + r²/c²) − 1))`` so that ½ r'² is the loss, which
keeps the rows robust whether or not the solve is. The face's plane is that of three of the
primitive's handles that lie on it (the widest triangle they make), so it moves with the
primitive's parameters and joints as the handles do; curved faces (a cylinder's side, a sphere)
are not observed this way.

:class:`ScanProblem` is a :class:`~vebuild.model.solver.Problem` with these rows appended after
all of its own (so that no row of the problem moves). Their Jacobian over the model parameters is
differenced as the problem's own handle rows are; the rows take part in the covariance but not
in the clicks' variance factor.

Layer 2 of DESIGN.md: numpy only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from vebuild.constants import ROBUST_SCALE

from .moved import apply_plan
from .residuals import FD_STEP
from .solver import Problem

Array = NDArray[np.float64]


@dataclass
class SurfaceObservation:
    """World ``points`` (n, 3) on the flat face ``face`` of ``node``, each with 1σ ``sigma`` (metres)."""

    node: str
    face: str
    points: Array
    sigma: float


def face_handles(prim: Any, face: str) -> tuple[tuple[int, int, int], float]:
    """Three handles of ``prim`` on the plane of its flat ``face`` (the widest triangle) and the sign
    that turns their plane's normal (b − a) × (c − a) outward (the mesh face's normal)."""
    mesh = prim.mesh(segments=8)
    if face not in mesh.face_names:
        raise ValueError(f"a {prim.TYPE} has no face {face!r}; its faces are {', '.join(mesh.face_names)}")
    tris = mesh.faces[mesh.face_ids == mesh.face_names.index(face) + 1]
    V = mesh.vertices
    a, b, c = V[tris[:, 0]], V[tris[:, 1]], V[tris[:, 2]]
    nrm = np.cross(b - a, c - a)
    area = np.linalg.norm(nrm, axis=1)
    n = nrm.sum(axis=0)
    if np.linalg.norm(n) < 1e-12:
        raise ValueError(f"face {face!r} of a {prim.TYPE} has no plane")
    n = n / np.linalg.norm(n)
    if np.abs((nrm / np.maximum(area, 1e-300)[:, None]) @ n).min() < 1 - 1e-9:
        raise ValueError(f"face {face!r} of a {prim.TYPE} is curved")
    H = prim.handles()
    size = float(np.ptp(V, axis=0).max())
    on = np.flatnonzero(np.abs((H - a[0]) @ n) <= 1e-7 * max(size, 1.0))
    best, best_area = None, 0.0
    for i in range(len(on)):
        for j in range(i + 1, len(on)):
            for k in range(j + 1, len(on)):
                w = np.cross(H[on[j]] - H[on[i]], H[on[k]] - H[on[i]])
                if np.linalg.norm(w) > best_area:
                    best, best_area = (int(on[i]), int(on[j]), int(on[k])), float(np.linalg.norm(w))
    if best is None or best_area <= 1e-12 * max(size, 1.0) ** 2:
        raise ValueError(f"face {face!r} of a {prim.TYPE} has fewer than three handles on its plane")
    w = np.cross(H[best[1]] - H[best[0]], H[best[2]] - H[best[0]])
    return best, float(np.sign(w @ n))


def robust(r: Array, c: float = ROBUST_SCALE) -> tuple[Array, Array]:
    """The soft-L1 loss put in the residual (module docstring) and its derivative dr'/dr."""
    z = (r / c) ** 2
    rp = np.sign(r) * np.sqrt(2.0 * c * c * (np.sqrt(1.0 + z) - 1.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.where(np.abs(r) > 1e-12, (1.0 + z) ** -0.5 * r / np.where(rp == 0, 1.0, rp), 1.0)
    return rp, d


class ScanProblem(Problem):
    """A :class:`~vebuild.model.solver.Problem` with point-to-face rows (the module docstring)."""

    def __init__(self, *args: Any, surfaces: Sequence[SurfaceObservation] = (), **kw: Any) -> None:
        super().__init__(*args, **kw)
        groups = []
        for s in surfaces:
            P = np.asarray(s.points, float).reshape(-1, 3)
            if not len(P) or s.node not in self.h_offset:
                continue
            (a, b, c), sign = face_handles(self.primitive_of(s.node), s.face)
            o = self.h_offset[s.node]
            groups.append((s, P, np.array([o + a, o + b, o + c]), sign))
        self.surfaces = groups
        n = sum(len(P) for _, P, _, _ in groups)
        self.rows_scan = np.arange(self.m, self.m + n)
        self.m += n
        self.n_scan = n

    def _scan_raw(self, H: Array) -> Array:
        """Signed distances (whitened, before the robust loss) of every scan point to its face."""
        out = []
        for s, P, rows, sign in self.surfaces:
            a, b, c = H[rows[0]], H[rows[1]], H[rows[2]]
            n = sign * np.cross(b - a, c - a)
            n = n / np.linalg.norm(n)
            out.append((P - a) @ n / s.sigma)
        return np.concatenate(out) if out else np.zeros(0)

    def evaluate(self, x: Array) -> Array:
        r = super().evaluate(x)
        if self.n_scan:
            _, H = self._posed(self.model_vector(x))
            r[self.rows_scan] = robust(self._scan_raw(H))[0]
        return r

    def jacobian(self, x: Array) -> Array | sparse.csr_matrix:
        J = super().jacobian(x)
        if not self.n_scan:
            return J
        xm = self.model_vector(x)
        T, H = self._posed(xm)
        r0 = self._scan_raw(H)
        _, d = robust(r0)
        used = np.unique(np.concatenate([rows for _, _, rows, _ in self.surfaces]))
        rows_, cols_, vals_ = [], [], []
        for j in self.layout.model.indices:
            if not np.isin(used, self.moves[j][1]).any():
                continue
            h = FD_STEP * max(1.0, abs(x[j]))
            xp = x.copy()
            xp[j] += h
            _, Hp = apply_plan(self.move_plan([j]), self.model, self.model_vector(xp), T, H, self.handle_positions)
            col = d * (self._scan_raw(Hp) - r0) / h
            nz = np.flatnonzero(col)
            rows_.append(self.rows_scan[nz])
            cols_.append(np.full(len(nz), j))
            vals_.append(col[nz])
        if not rows_:
            return J
        R, C, V = np.concatenate(rows_), np.concatenate(cols_), np.concatenate(vals_)
        if sparse.issparse(J):
            return (J + sparse.coo_matrix((V, (R, C)), shape=J.shape)).tocsr()
        J[R, C] = V
        return J

    def describe_row(self, row: int) -> str:
        if self.n_scan and self.rows_scan[0] <= row <= self.rows_scan[-1]:
            k = row - int(self.rows_scan[0])
            for s, P, _, _ in self.surfaces:
                if k < len(P):
                    return f"scan point {k} on {s.node}:{s.face}"
                k -= len(P)
        return super().describe_row(row)
