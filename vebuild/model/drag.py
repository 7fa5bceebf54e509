"""Drags: the edit API behind interactive modelling (paper §3, Figures 5 and 7).

A drag is three calls: :class:`DragSession` (start: a handle of a node, grabbed in a photo),
:meth:`DragSession.move` (the mouse is at a pixel: solve, return the updated model and its
projected edges) and :meth:`DragSession.release` (the vertex becomes a fixed pin). Everything that
does not change during a drag (the least-squares problem, which observations a parameter moves)
is built once at the start; each move warm-starts from the previous one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..camera import ImageCamera, project, world_to_camera
from .residuals import EdgeObservation, Pin
from .scene import Model
from .solver import Problem, ProblemOptions

Array = NDArray[np.float64]

DRAG_TOL = 1e-8
DRAG_DAMPING = 1e-6
#: A warm-started move converges in a few iterations; one the constraints cannot follow may not
#: converge at all, and must not stall the screen while it tries.
DRAG_MAX_ITERATIONS = 25


@dataclass
class DragResult:
    """After one move: the model's parameter vector, and every moved edge projected into each photo.

    edges_px : photo → node → list of (edge name, (u1, v1, u2, v2)).
    fixed_error_px : the largest distance of a fixed pin from its handle's projection.
    handle_px : where the dragged handle now projects in the drag's photo.
    """

    x: Array
    moved: list[str]
    edges_px: dict[str, dict[str, list[tuple[str, tuple[float, float, float, float]]]]]
    handle_px: Array
    fixed_error_px: float


def project_edges(model: Model, camera: ImageCamera, nodes: Sequence[str], x: Array | None = None,
                  transforms: Mapping[str, Array] | None = None) -> dict[str, list[tuple[str, tuple]]]:
    """Every edge of the given primitive nodes projected into one photo (the white edges of §3)."""
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
        uv = project(camera.K, camera.R, camera.C, world)
        idx = {h: i for i, h in enumerate(node.primitive.handle_names())}
        out[name] = [(e, (*uv[idx[a]], *uv[idx[b]])) for e, a, b in node.primitive.edges()
                     if depth[idx[a]] > 0 and depth[idx[b]] > 0]
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
        self.pin = Pin(photo, node, handle, project(cam.K, cam.R, cam.C, model.handle_world(node, handle)),
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
        edges = {cid: project_edges(self.model, self.cameras[cid], self.moved, xm, T) for cid in self.edges_into}
        r = sol.residuals * self.problem.sigma  # the solve's own final residuals: no second evaluation
        fixed = [np.linalg.norm(r[self.problem.rows_pin[i]]) for i, p in enumerate(self.problem.pins)
                 if p is not self.pin]
        cam = self.cameras[self.photo]
        handle_px = project(cam.K, cam.R, cam.C, self.model.handle_world(self.node, self.handle, xm, T))
        return DragResult(xm, self.moved, edges, handle_px, float(max(fixed, default=0.0)))

    def release(self) -> Pin:
        """Keep the result in the model and return the grabbed handle as a fixed pin."""
        self.model.set_vector(self.problem.model_vector(self.x))
        return Pin(self.photo, self.node, self.handle, self.pin.uv.copy(), fixed=True)

    def cancel(self) -> None:
        """Leave the model as it was before the drag."""
        self.x = self.x_start.copy()
