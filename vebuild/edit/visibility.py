"""Which parts of the model's edges a photo's camera sees, by the model's own ID buffer: the
modelling screen draws an edge's seen parts solid and its hidden parts (behind another face of the
model, from that camera) dashed and dim.

Each edge is sampled in the world every :data:`SAMPLE_PX` photo pixels; a sample is hidden when
every pixel of the 3 × 3 pixels around it in the ID buffer (:meth:`vebuild.render.renderer.Renderer.id_buffer`
of the photo's calibrated camera, scaled to at most :data:`ID_LONG_SIDE_PX` on its long side) shows
a face nearer the camera than the sample by more than :data:`DEPTH_TOLERANCE` of its depth. The
neighbourhood keeps an edge's own faces from hiding it: beside a seen edge one of those pixels shows
one of its faces at its own depth, or what lies beyond it. A sample outside the ID buffer counts as
seen (nothing there says otherwise).

Plain numpy over the ID buffer; the screen renders it (:mod:`vebuild.edit.photo_view`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild import camera as cam_math
from vebuild.camera import ImageCamera

Array = NDArray[np.float64]

#: The ID buffer of a photo's camera is rendered at most this many pixels on its long side (a
#: 24-megapixel photo's own size would cost a software renderer seconds per model change).
ID_LONG_SIDE_PX = 1600
#: A face nearer than the sample by more than this share of its depth hides it: 0.5 %, as
#: texture extraction's edge band (:data:`vebuild.texture.id_edges.EDGE_SHRINK`): 1.5 cm at 3 m.
DEPTH_TOLERANCE = 5e-3
#: Samples along an edge, every this many photo pixels (at least two an edge, at most MAX_SAMPLES).
SAMPLE_PX = 3.0
MAX_SAMPLES = 600


@dataclass(frozen=True)
class EdgeRun:
    """Consecutive samples of one edge that are all seen or all hidden: their places in the photo's
    pixels (through its lens), (n, 2), n ≥ 2; neighbouring runs share their end sample."""

    points: Array
    visible: bool


def id_camera(cam: ImageCamera) -> ImageCamera:
    """The photo's camera at the size its ID buffer is rendered (:data:`ID_LONG_SIDE_PX`)."""
    s = min(1.0, ID_LONG_SIDE_PX / max(cam.width, cam.height))
    return cam if s == 1.0 else cam.scaled(s)


def edge_samples(ends: Mapping[object, tuple[Array, Array]], cam: ImageCamera) -> dict[object, Array]:
    """World samples (n, 3) along each edge (world ends a, b, both in front of ``cam``), about
    :data:`SAMPLE_PX` apart in the photo; edges with an end behind the camera are left out. All
    edges at once: the samples are those of ``np.linspace(0, 1, n)`` along each, bit for bit."""
    if not ends:
        return {}
    keys = list(ends)
    A = np.array([np.asarray(ends[k][0], float) for k in keys]).reshape(-1, 3)
    B = np.array([np.asarray(ends[k][1], float) for k in keys]).reshape(-1, 3)
    AB = np.stack([A, B], axis=1).reshape(-1, 3)  # a0, b0, a1, b1, ...
    z = cam_math.world_to_camera(cam.R, cam.C, AB)[:, 2].reshape(-1, 2)
    front = np.all(z > 0, axis=1)
    uv = cam_math.project(cam.K, cam.R, cam.C, AB).reshape(-1, 2, 2)
    length = np.linalg.norm(uv[:, 1] - uv[:, 0], axis=1)
    n = np.minimum(MAX_SAMPLES, np.maximum(2, np.ceil(length / SAMPLE_PX) + 1)).astype(int)
    kept = np.flatnonzero(front)
    if not len(kept):
        return {}
    n = n[kept]
    first = np.cumsum(n) - n  # each edge's first sample
    step = np.repeat(1.0 / (n - 1), n)  # as linspace: the index times 1 / (n - 1), the last one 1
    t = (np.arange(int(n.sum())) - np.repeat(first, n)) * step
    t[first + n - 1] = 1.0
    X = np.repeat(A[kept], n, axis=0) + t[:, None] * np.repeat(B[kept] - A[kept], n, axis=0)
    return dict(zip([keys[i] for i in kept], np.split(X, first[1:]), strict=True))


def seen(X: Array, cam: ImageCamera, ids: NDArray[np.int32], depth: NDArray[np.float32]) -> NDArray[np.bool_]:
    """Whether each world point of X (n, 3) is seen from ``cam`` (the camera of the ID buffer
    ``ids``, ``depth``: :meth:`~vebuild.render.renderer.Renderer.id_buffer`), by the rule of the
    module docstring."""
    X = np.asarray(X, float).reshape(-1, 3)
    z = cam_math.world_to_camera(cam.R, cam.C, X)[:, 2]
    uv = cam_math.project(cam.K, cam.R, cam.C, X, cam.lens).reshape(-1, 2)
    col, row = np.floor(uv[:, 0]).astype(np.intp), np.floor(uv[:, 1]).astype(np.intp)
    h, w = ids.shape
    inside = (col >= 0) & (row >= 0) & (col < w) & (row < h) & (z > 0)
    visible = ~inside
    limit = z * (1.0 - DEPTH_TOLERANCE)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            r, c = np.clip(row + dr, 0, h - 1), np.clip(col + dc, 0, w - 1)
            visible |= inside & ((ids[r, c] == 0) | (depth[r, c] >= limit))
    return visible


def runs(X: Array, visible: NDArray[np.bool_], photo_cam: ImageCamera, uv: Array | None = None) -> list[EdgeRun]:
    """The samples X (n, 3) of one edge as runs of equal visibility, in the photo's pixels (``uv``:
    their places there, when already projected)."""
    if uv is None:
        uv = cam_math.project(photo_cam.K, photo_cam.R, photo_cam.C, X, photo_cam.lens).reshape(-1, 2)
    cuts = np.flatnonzero(np.diff(visible.astype(np.int8))) + 1  # the first sample of each new run
    starts, stops = np.r_[0, cuts], np.r_[cuts, len(X) - 1]  # a run reaches the next one's first sample
    return [EdgeRun(uv[a:b + 1].copy(), bool(visible[a])) for a, b in zip(starts, stops, strict=True) if b > a]


def edge_runs(ends: Mapping[object, tuple[Array, Array]], photo_cam: ImageCamera, id_cam: ImageCamera,
              ids: NDArray[np.int32], depth: NDArray[np.float32]) -> dict[object, list[EdgeRun]]:
    """Every edge (world ends by key) as its seen and hidden runs in the photo (all samples judged
    and projected at once)."""
    samples = edge_samples(ends, photo_cam)
    if not samples:
        return {}
    X = np.concatenate(list(samples.values()))
    vis = seen(X, id_cam, ids, depth)
    uv = cam_math.project(photo_cam.K, photo_cam.R, photo_cam.C, X, photo_cam.lens).reshape(-1, 2)
    out = {}
    at = 0
    for key, Xe in samples.items():
        n = len(Xe)
        out[key] = runs(Xe, vis[at:at + n], photo_cam, uv[at:at + n])
        at += n
    return out


def clip_segment(p: Sequence[float], width: float, height: float) -> tuple[float, float, float, float] | None:
    """The part of segment (u1, v1, u2, v2) inside the photo [0, width] × [0, height] (Liang–Barsky),
    or None where none of it is."""
    u1, v1, u2, v2 = (float(t) for t in p)
    du, dv = u2 - u1, v2 - v1
    t0, t1 = 0.0, 1.0
    for q, r in ((-du, u1), (du, width - u1), (-dv, v1), (dv, height - v1)):
        if abs(q) < 1e-12:
            if r < 0:
                return None
            continue
        t = r / q
        if q < 0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
        if t0 > t1:
            return None
    return u1 + t0 * du, v1 + t0 * dv, u1 + t1 * du, v1 + t1 * dv


def clip_polyline(P: NDArray[np.float64], width: float, height: float) -> list[NDArray[np.float64]]:
    """The parts of polyline ``P`` (n, 2) inside the photo [0, width] × [0, height], each a polyline
    of its own: :func:`clip_segment` over every segment at once (the overlay draws thousands of
    edge samples a frame)."""
    P = np.asarray(P, float).reshape(-1, 2)
    if len(P) < 2:
        return []
    lo, hi = P.min(axis=0), P.max(axis=0)
    if lo[0] >= 0.0 and lo[1] >= 0.0 and hi[0] <= width and hi[1] <= height:  # all on the photo
        return [P]
    if hi[0] < 0.0 or hi[1] < 0.0 or lo[0] > width or lo[1] > height:  # all beyond one side
        return []
    A, d = P[:-1], P[1:] - P[:-1]
    t0, t1 = np.zeros(len(A)), np.ones(len(A))
    ok = np.ones(len(A), bool)
    for q, r in ((-d[:, 0], A[:, 0]), (d[:, 0], width - A[:, 0]), (-d[:, 1], A[:, 1]), (d[:, 1], height - A[:, 1])):
        flat = np.abs(q) < 1e-12
        ok &= ~flat | (r >= 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(flat, 0.0, r / np.where(flat, 1.0, q))
        t0 = np.where(~flat & (q < 0), np.maximum(t0, t), t0)
        t1 = np.where(~flat & (q > 0), np.minimum(t1, t), t1)
    ok &= t0 <= t1
    Q0, Q1 = A + t0[:, None] * d, A + t1[:, None] * d
    idx = np.flatnonzero(ok)
    if not len(idx):
        return []
    joined = ok[:-1] & ok[1:] & (t1[:-1] == 1.0) & (t0[1:] == 0.0)  # segment k runs on into k + 1
    runs_on = (np.diff(idx) == 1) & joined[idx[:-1]]
    return [np.vstack((Q0[g[0]], Q1[g])) for g in np.split(idx, np.flatnonzero(~runs_on) + 1)]
