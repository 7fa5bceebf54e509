"""Drags: the edit API behind interactive modelling (paper §3, Figures 5 and 7).

A drag is three calls: :class:`DragSession` (start: a handle of a node, grabbed in a photo),
:meth:`DragSession.move` (the mouse is at a pixel: solve, return the updated model and its
projected edges) and :meth:`DragSession.release` (the vertex becomes a fixed pin). Everything that
does not change during a drag (the least-squares problem, which observations a parameter moves)
is built once at the start; each move warm-starts from the previous one.

Through a photo's lens (its :attr:`~vebuild.camera.ImageCamera.lens`) the mouse, the pins and the
projected handles are all in the photo's own (distorted) pixels, as the solver's residuals are; a
straight model edge is a curve there, drawn as a polyline (:func:`lens_polyline`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.camera import PINHOLE, ImageCamera, Lens, distort_pixels, project, world_to_camera

from .residuals import EdgeObservation, Pin
from .scene import Model
from .solver import Problem, ProblemOptions

Array = NDArray[np.float64]

DRAG_TOL = 1e-8
DRAG_DAMPING = 1e-6
#: A warm-started move converges in a few iterations; one the constraints cannot follow may not
#: converge at all, and must not stall the screen while it tries.
DRAG_MAX_ITERATIONS = 25
#: The most a drawn edge may stray from the curve a straight 3D edge makes in a distorted photo
#: (pixels): a quarter of a click's noise, below what a screen shows.
CURVE_TOL_PX = 0.5
#: A polyline has at most 2**this pieces (far more than any lens bends an edge into).
CURVE_MAX_DEPTH = 12


def lens_polyline(K: ArrayLike, lens: Lens, a: ArrayLike, b: ArrayLike, tol: float = CURVE_TOL_PX) -> Array:
    """(n, 2) pixels along the curve the lens ``k1`` makes of the straight segment a–b of the
    pinhole image (pixels where the pinhole K puts its ends): :func:`lens_polylines` of one."""
    return lens_polylines(K, lens, np.asarray(a, float)[None], np.asarray(b, float)[None], tol)[0]


def lens_polylines(K: ArrayLike, lens: Lens, a: ArrayLike, b: ArrayLike, tol: float = CURVE_TOL_PX) -> list[Array]:
    """For each straight segment a[i]–b[i] of the pinhole image ((n, 2) pixels where the pinhole K
    puts the ends), the (m, 2) pixels along the curve the lens ``k1`` makes of it: the distorted
    ends and, between them, as many points of the curve as keep each chord within ``tol`` of it.

    The step follows the distortion: a piece is split in two until the curve at a quarter, half
    and three quarters of it lies within tol/2 of its chord (halved because the curve may bend
    most between those checks); a pinhole (k1 = 0) keeps each segment. Straight lines of the
    pinhole image are the images of straight 3D lines, so this draws 3D edges through the lens.
    All segments are refined together, one level at a time (a drag redraws dozens per move).
    """
    a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
    if lens.is_pinhole or not len(a):  # (np.split of nothing would give one empty piece)
        return [np.array([p, q]) for p, q in zip(a, b, strict=True)]
    K = np.asarray(K, float)
    ticks = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    seg = np.arange(len(a))
    lo, hi = np.zeros(len(a)), np.ones(len(a))
    done_seg, done_lo = [], []
    for depth in range(CURVE_MAX_DEPTH + 1):
        t = lo[:, None] + (hi - lo)[:, None] * ticks
        q = distort_pixels(K, a[seg, None] + t[..., None] * (b - a)[seg, None], lens)  # (m, 5, 2)
        chord = q[:, 4] - q[:, 0]
        L = np.maximum(np.linalg.norm(chord, axis=-1), 1e-12)[:, None]
        rel = q[:, 1:4] - q[:, :1]
        off = np.abs(rel[..., 0] * chord[:, None, 1] - rel[..., 1] * chord[:, None, 0]) / L
        ok = np.all(off <= 0.5 * tol, axis=1) if depth < CURVE_MAX_DEPTH else np.ones(len(lo), bool)
        done_seg.append(seg[ok])
        done_lo.append(lo[ok])
        mid = 0.5 * (lo + hi)
        bad = ~ok
        seg = np.concatenate([seg[bad], seg[bad]])
        lo, hi = np.concatenate([lo[bad], mid[bad]]), np.concatenate([mid[bad], hi[bad]])
        if not len(seg):
            break
    segs, los = np.concatenate(done_seg), np.concatenate(done_lo)
    # Each segment's pieces' starts, then its end (t = 1): distorted all at once, then split.
    all_seg = np.concatenate([segs, np.arange(len(a))])
    all_t = np.concatenate([los, np.ones(len(a))])
    order = np.lexsort((all_t, all_seg))
    all_seg, all_t = all_seg[order], all_t[order]
    q = distort_pixels(K, a[all_seg] + all_t[:, None] * (b - a)[all_seg], lens)
    return np.split(q, np.searchsorted(all_seg, np.arange(1, len(a))))


@dataclass
class DragResult:
    """After one move: the model's parameter vector, and every moved edge projected into each photo.

    edges_px : photo → node → list of (edge name, (n, 2) pixels along the edge's image): its
        two ends, or, through a distorting lens, the polyline of :func:`lens_polyline`.
    fixed_error_px : the largest distance of a fixed pin from its handle's projection.
    handle_px : where the dragged handle now projects in the drag's photo.
    """

    x: Array
    moved: list[str]
    edges_px: dict[str, dict[str, list[tuple[str, Array]]]]
    handle_px: Array
    fixed_error_px: float


def _edge_ends(model: Model, camera: ImageCamera, nodes: Sequence[str], x: Array | None,
               transforms: Mapping[str, Array] | None, lens: Lens) -> dict[str, list[tuple[str, Array, Array]]]:
    x = model.vector() if x is None else x
    T = transforms if transforms is not None else model.world_transforms(x)
    out = {}
    for name in nodes:
        node = model.node(name)
        if node.primitive is None:
            continue
        hs = node.primitive.handles(x[model.slices[name][1]])
        world = hs @ T[name][:3, :3].T + T[name][:3, 3]
        depth = world_to_camera(camera.R, camera.C, world)[:, 2]
        uv = project(camera.K, camera.R, camera.C, world, lens)
        idx = {h: i for i, h in enumerate(node.primitive.handle_names())}
        out[name] = [(e, uv[idx[a]], uv[idx[b]]) for e, a, b in node.primitive.edges()
                     if depth[idx[a]] > 0 and depth[idx[b]] > 0]
    return out


def project_edges(model: Model, camera: ImageCamera, nodes: Sequence[str], x: Array | None = None,
                  transforms: Mapping[str, Array] | None = None) -> dict[str, list[tuple[str, tuple]]]:
    """Every edge of the given primitive nodes projected into one photo (the white edges of §3):
    node → (edge, (u1, v1, u2, v2)), its ends where the photo's lens puts them (an edge in front
    of the camera only). Through a distorting lens the edge between them is a curve:
    :func:`project_edge_curves` draws it."""
    return {n: [(e, (*pa, *pb)) for e, pa, pb in edges]
            for n, edges in _edge_ends(model, camera, nodes, x, transforms, camera.lens).items()}


def project_edge_curves(model: Model, camera: ImageCamera, nodes: Sequence[str], x: Array | None = None,
                        transforms: Mapping[str, Array] | None = None,
                        tol: float = CURVE_TOL_PX) -> dict[str, list[tuple[str, Array]]]:
    """As :func:`project_edges`, each edge as the (n, 2) polyline of its image through the photo's
    lens (:func:`lens_polyline`, within ``tol`` pixels of the true curve; two points for a pinhole)."""
    ends = _edge_ends(model, camera, nodes, x, transforms, PINHOLE)  # the pinhole's: straight lines
    flat = [(n, e, pa, pb) for n, edges in ends.items() for e, pa, pb in edges]
    curves = lens_polylines(camera.K, camera.lens, np.array([f[2] for f in flat]).reshape(-1, 2),
                            np.array([f[3] for f in flat]).reshape(-1, 2), tol)
    out: dict[str, list[tuple[str, Array]]] = {n: [] for n in ends}
    for (n, e, _, _), q in zip(flat, curves, strict=True):
        out[n].append((e, q))
    return out


def drag_nodes(model: Model, node: str) -> list[str]:
    """What a drag on ``node`` may change: the node, and, if its own joint cannot move, the nearest
    ancestor that can (dragging a table leg moves the table)."""
    free = [node]
    n = model.node(node)
    while not n.joint.dof_names and n.parent is not None:
        n = model.node(n.parent)
        free.append(n.name)
    return free


class DragSession:
    """One drag of one handle of one node in one photo."""

    def __init__(self, model: Model, cameras: Mapping[str, ImageCamera], pins: Sequence[Pin],
                 edges: Sequence[EdgeObservation], photo: str, node: str, handle: str, *,
                 click_sigma_px: float = 1.0, edges_into: Sequence[str] | None = None):
        if node not in model.index:
            raise KeyError(f"no node named '{node}'")
        prim = model.node(node).primitive
        if prim is None or handle not in prim.handle_names():
            raise KeyError(f"node '{node}' has no handle '{handle}'")
        self.model = model
        self.cameras = cameras
        # The photos each move projects the moved edges into (all by default; none for a caller
        # that draws its own).
        self.edges_into = list(cameras) if edges_into is None else [c for c in edges_into if c in cameras]
        self.photo, self.node, self.handle = photo, node, handle
        self.free = drag_nodes(model, node)
        root = self.free[-1]
        self.moved = model.subtree(root)
        moved = set(self.moved)
        # The grabbed handle replaces any pin it had in this photo; other pins of the moving
        # subtree (fixed vertices) and its edge observations stay in the problem.
        self.other_pins = [p for p in pins if not (p.photo == photo and p.node == node and p.handle == handle)]
        cam = cameras[photo]
        self.pin = Pin(photo, node, handle, project(cam.K, cam.R, cam.C, model.handle_world(node, handle), cam.lens),
                       fixed=False)
        obs = [p for p in self.other_pins if p.node in moved and p.fixed] + [self.pin]
        # Paper Figure 7: until a vertex of the node is fixed, a drag moves the node as a whole
        # (its joint's degrees of freedom); once one is, its sizes may change as well. A node tied
        # to a marker has one already: its anchor handle sits on the marker.
        anchored = model.node(node).joint.type == "marker"
        held = () if anchored or any(p.node == node for p in obs[:-1]) else \
            [f"{node}.{name}" for name in prim.PARAMS]
        self.problem = Problem(model, cameras, obs, [e for e in edges if e.node in moved],
                               options=ProblemOptions(click_sigma_px=click_sigma_px, free_nodes=self.free, held=held))
        self._pin_index = len(self.problem.pins) - 1
        self.x = self.problem.x0()
        self.x_start = self.x.copy()

    def move(self, uv: ArrayLike) -> DragResult:
        """The mouse is at uv: solve (warm-started) and return the new state."""
        self.problem.set_pin_pixel(self._pin_index, uv)
        # Warm start from the previous mouse position: near-Gauss–Newton steps, and a tolerance
        # far below what a screen shows (a relative cost change of 1e-8 is ~1e-4 px here).
        sol = self.problem.solve(self.x, tol=DRAG_TOL, damping=DRAG_DAMPING, max_iterations=DRAG_MAX_ITERATIONS)
        self.x = sol.x
        xm = self.problem.model_vector(self.x)
        T = self.problem.transforms(xm)
        edges = {cid: project_edge_curves(self.model, self.cameras[cid], self.moved, xm, T) for cid in self.edges_into}
        r = sol.residuals * self.problem.sigma  # the solve's own final residuals: no second evaluation
        fixed = [np.linalg.norm(r[self.problem.rows_pin[i]]) for i, p in enumerate(self.problem.pins)
                 if p is not self.pin]
        cam = self.cameras[self.photo]
        handle_px = project(cam.K, cam.R, cam.C, self.model.handle_world(self.node, self.handle, xm, T), cam.lens)
        return DragResult(xm, self.moved, edges, handle_px, float(max(fixed, default=0.0)))

    def release(self) -> Pin:
        """Keep the result in the model and return the grabbed handle as a fixed pin."""
        self.model.set_vector(self.problem.model_vector(self.x))
        return Pin(self.photo, self.node, self.handle, self.pin.uv.copy(), fixed=True)

    def cancel(self) -> None:
        """Leave the model as it was before the drag."""
        self.x = self.x_start.copy()
