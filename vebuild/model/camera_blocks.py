"""The cameras' part of the solver's residuals when re-calibrating: each photo's K, R, C and k1 at
a point of the vector, and the rows of the priors that hold them.

A photo's camera block (:class:`~vebuild.model.layout.Block`) holds its pose and, where its
intrinsics are refined, its own (δf, δcx, δcy[, k1]) or, for a camera group's photo, a pointer to
its group's one block: every photo of a group has the same K and k1 at every x. A camera's prior is
its calibration covariance over its own unknowns; a group's (δf, δcx, δcy[, k1]) are held once, by
the group's joint prior (the calibration record's ``camera_groups[].covariance``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, Lens, exp_so3

from .layout import ParameterLayout

Array = NDArray[np.float64]
Index = NDArray[np.intp]


def whitening(covariance: Array) -> Array:
    """L with Lᵀ L = covariance⁻¹ (from its eigen-decomposition; a zero variance held at 1e-9 σ)."""
    c = np.asarray(covariance, float)
    w, V = np.linalg.eigh(0.5 * (c + c.T))
    return np.asarray((V / np.sqrt(np.maximum(w, 1e-18))).T)


class CameraBlocks:
    """K, R, C and k1 of every photo at x, and the cameras' and groups' prior rows."""

    layout: ParameterLayout
    cam_ids: list[str]
    cameras: dict[str, ImageCamera]
    _prior_L: dict[str, Array]
    _prior_at: dict[str, Array]  # per re-calibrated camera: the block's values where its prior is 0
    #: Per camera group: its prior's whitening and where it is 0 (no change of the group's K, k1 as
    #: calibrated), and its rows.
    _group_L: dict[str, Array]
    _group_at: dict[str, Array]
    rows_prior_cam: dict[str, Index]
    rows_prior_group: dict[str, Index]

    def camera_matrices(self, x: Array) -> dict[str, tuple[Array, Array, Array]]:
        """K, R, C of every photo at x (as calibrated where the camera is not being solved)."""
        out = {}
        for cid in self.cam_ids:
            cam = self.cameras[cid]
            blk = self.layout.cameras.get(cid)
            if blk is None:
                out[cid] = (cam.K, cam.R, cam.C)
                continue
            K = cam.K.copy()
            if blk.intrinsics:
                o = blk.intrinsics_start
                df, dcx, dcy = x[o : o + 3]
                K[0, 0] = K[1, 1] = cam.K[0, 0] + df
                K[0, 2] = cam.K[0, 2] + dcx
                K[1, 2] = cam.K[1, 2] + dcy
            o = blk.pose_start
            out[cid] = (K, exp_so3(x[o : o + 3]) @ cam.R, x[o + 3 : o + 6])
        return out

    def camera_k1(self, x: Array) -> dict[str, float]:
        """The lens distortion k1 of every photo at x (as calibrated where it is not refined)."""
        out = {}
        for cid in self.cam_ids:
            blk = self.layout.cameras.get(cid)
            k = None if blk is None else blk.k1_index
            out[cid] = float(self.cameras[cid].lens.k1) if k is None else float(x[k])
        return out

    def camera_lenses(self, x: Array) -> dict[str, Lens]:
        """Every photo's lens at x: k1 as :meth:`camera_k1`, k2 always as calibrated (never refined)."""
        k1 = self.camera_k1(x)
        return {cid: Lens(k1[cid], self.cameras[cid].lens.k2) for cid in self.cam_ids}

    def _prior_rows(self, start: int) -> int:
        """Lay out the cameras' then the groups' prior rows from row ``start``; the next free row."""
        rows = start
        self.rows_prior_cam, self.rows_prior_group = {}, {}
        for cid, blk in self.layout.cameras.items():
            self.rows_prior_cam[cid] = np.arange(rows, rows + len(blk))
            rows += len(blk)
        for gid, blk in self.layout.groups.items():
            self.rows_prior_group[gid] = np.arange(rows, rows + len(blk))
            rows += len(blk)
        return rows

    def _camera_prior_residuals(self, x: Array, r: Array) -> None:
        for cid, blk in self.layout.cameras.items():
            r[self.rows_prior_cam[cid]] = self._prior_L[cid] @ (x[blk.slice] - self._prior_at[cid])
        for gid, blk in self.layout.groups.items():
            r[self.rows_prior_group[gid]] = self._group_L[gid] @ (x[blk.slice] - self._group_at[gid])

    def _camera_prior_jacobian(self, put: Callable[[Any, Any, Any], None]) -> None:
        """The prior rows' derivatives (linear: exact)."""
        for rows, blk, L in [*[(self.rows_prior_cam[c], b, self._prior_L[c]) for c, b in self.layout.cameras.items()],
                             *[(self.rows_prior_group[g], b, self._group_L[g]) for g, b in self.layout.groups.items()]]:
            rr, cc = np.meshgrid(rows, blk.indices, indexing="ij")
            put(rr, cc, L)

    def describe_prior_row(self, row: int) -> str | None:
        """Which camera's or camera group's calibration prior ``row`` is, if any."""
        for cid, prior_rows in self.rows_prior_cam.items():
            if prior_rows[0] <= row <= prior_rows[-1]:
                return f"the calibration of photo '{cid}'"
        for gid, prior_rows in self.rows_prior_group.items():
            if prior_rows[0] <= row <= prior_rows[-1]:
                return f"the calibration of camera group '{gid}'"
        return None


@dataclass(frozen=True)
class SharedIntrinsics:
    """A camera group in a re-calibration: its photos, its shared K and k1 as calibrated, and their
    joint covariance over (f, cx, cy, k1) from the vanishing points (the calibration record's
    ``camera_groups[].covariance``); k1 is refined where ``refine_k1``."""

    photos: tuple[str, ...]
    K: Array
    k1: float
    covariance: Array
    refine_k1: bool


def group_prior(blk_len: int, covariance: Array) -> Array:
    """A camera group's prior whitening over its block (δf, δcx, δcy[, k1]) from the group's joint
    4×4 covariance over (f, cx, cy, k1)."""
    return whitening(np.asarray(covariance, float)[:blk_len, :blk_len])


def shared_cameras(cameras: Mapping[str, ImageCamera], groups: Mapping[str, SharedIntrinsics]
                   ) -> dict[str, ImageCamera]:
    """``cameras`` with each camera group's photos given their group's K and k1: the point the
    group's shared unknowns start from."""
    out = dict(cameras)
    for g in groups.values():
        for cid in g.photos:
            c = out[cid]
            out[cid] = ImageCamera(cid, np.asarray(g.K, float).copy(), c.R, c.C, c.width, c.height,
                                   covariance=c.covariance, lens=Lens(float(g.k1), c.lens.k2))
    return out
