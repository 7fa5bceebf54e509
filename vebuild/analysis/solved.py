"""The solved model with the joint covariance of its parameters, and points tied to it.

A point is tied to the model, so that its world position is a function of the solved parameters:
a handle (``node:handle``), a point on a face kept in *normalised* local coordinates of its
primitive (x / width, y / depth, z / height for a box; the angle and height fraction on a cylinder
or frustum; the direction from a sphere's centre; on a room, the place along its nearest wall,
:meth:`~vebuild.model.room.Room.to_coords`), fixed when the point is placed, so that when a
parameter changes the point stays at the same place on the face, the face scaled with it; or a
marker. How points are written and picked: :mod:`vebuild.analysis.points`; what is measured
between them: :mod:`vebuild.analysis.measure`.

``vebuild solve`` stores the joint covariance of the model's parameters (and, when it
re-calibrated, of the markers) in ``model_solution.covariance``; :class:`SolvedModel` holds it over
one parameter vector: the solve's free parameters (radians), then the re-calibrated markers, then
the other markers with their calibration 1σ per axis, independent of the model and of each other.

Layer 6 of DESIGN.md: numpy only, no GL.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import ProjectError, VebuildError
from vebuild.model.primitives import Primitive, Sphere, _Round
from vebuild.model.room import Room
from vebuild.model.scene import Model
from vebuild.project.units import METRES, LengthUnit, length_unit

if TYPE_CHECKING:
    from vebuild.project import Project


Array = NDArray[np.float64]


class MeasureError(VebuildError):
    """A point, node, face or handle that does not exist, or a point off every surface."""


# ----------------------------------------------------------------------------------------------
# Points


def check_model_solution(project: Project) -> None:
    """``model_solution`` fits the model: its nodes are nodes of ``model.nodes``, and its covariance
    matrix is square with one row and one column per entry of its parameter list.

    Raises ProjectError naming the file and the JSON path (nothing to check if the project has not
    been solved).
    """
    from vebuild.project import json_path

    sol = project.data.get("model_solution")
    if not sol:
        return
    path = project.path
    nodes = [n["name"] for n in (project.data.get("model") or {}).get("nodes", [])]
    for name in sol.get("nodes") or {}:
        if name not in nodes:
            shown = ", ".join(repr(n) for n in nodes[:10]) + (f" and {len(nodes) - 10} more" if len(nodes) > 10 else "")
            raise ProjectError(path, json_path(["model_solution", "nodes", name]),
                               f"a solution for the node {name!r}, but $.model.nodes has no node of that name (the "
                               f"nodes are: {shown or 'none'}); run `vebuild solve` again")
    rec = sol.get("covariance")
    if rec:
        n = len(rec["parameters"])
        matrix = rec["matrix"]
        if len(matrix) != n:
            raise ProjectError(path, "$.model_solution.covariance.matrix",
                               f"expected a square {n}×{n} matrix (a row per entry of "
                               f"$.model_solution.covariance.parameters), found {len(matrix)} rows")
        for k, row in enumerate(matrix):
            if len(row) != n:
                raise ProjectError(path, f"$.model_solution.covariance.matrix[{k}]",
                                   f"expected a square {n}×{n} matrix (a column per entry of "
                                   f"$.model_solution.covariance.parameters), found a row of {len(row)} entries")


@dataclass(frozen=True)
class Point:
    """A point tied to the model: a handle, a point on a face (normalised coordinates) or a marker."""

    label: str
    kind: str  # "handle", "surface" or "marker"
    node: str | None = None
    handle: str | None = None
    face: str | None = None
    coords: tuple[float, ...] | None = None  # normalised local coordinates (3)
    marker: str | None = None


def to_coords(prim: Primitive, local: Array, snap_face: str | None = None) -> Array:
    """Normalised coordinates of a local point on ``prim`` at its own parameters (see the module).

    ``snap_face``: put a point of a faceted curved surface (a pick on the mesh) onto the true one.
    """
    p = prim.params
    local = np.asarray(local, float)
    if isinstance(prim, Room):  # along its walls: a point stays on its wall as the corners move
        return prim.to_coords(local)
    if isinstance(prim, _Round):
        rb, rt, h = (float(v) for v in prim._radii(p))
        zeta = local[2] / h
        r = rb + (rt - rb) * zeta
        ab = local[:2] / r if r > 1e-12 else np.zeros(2)
        if snap_face == "side" and np.linalg.norm(ab) > 0:
            ab = ab / np.linalg.norm(ab)
        return np.array([ab[0], ab[1], zeta])
    if isinstance(prim, Sphere):
        c = local / p[0]
        if snap_face == "surface":
            d = c - [0.0, 0.0, 1.0]
            c = [0.0, 0.0, 1.0] + d / np.linalg.norm(d)
        return np.asarray(c, float)
    return local / _box_scale(prim, p)


def from_coords(prim: Primitive, params: Array, coords: Array) -> Array:
    """The local point of normalised ``coords`` on ``prim`` with trial ``params``."""
    c = np.asarray(coords, float)
    if isinstance(prim, Room):
        return prim.from_coords(c, params)
    if isinstance(prim, _Round):
        rb, rt, h = (float(v) for v in prim._radii(np.asarray(params, float)))
        r = rb + (rt - rb) * c[2]
        return np.array([c[0] * r, c[1] * r, c[2] * h])
    if isinstance(prim, Sphere):
        return c * params[0]
    return c * _box_scale(prim, params)


def _box_scale(prim: Primitive, p: Array) -> Array:
    """(width, depth, height) of a quad (height 1: it is flat), box or wedge."""
    if prim.TYPE == "quad":
        return np.array([p[0], p[1], 1.0])
    if prim.TYPE in ("box", "wedge"):
        return np.asarray(p[:3], float)
    raise MeasureError(f"a {prim.TYPE} has no normalised coordinates in this version")


# ----------------------------------------------------------------------------------------------
# The solved model and its covariance


@dataclass
class SolvedModel:
    """The solved model with the joint covariance of the parameters it was solved for.

    The vector it propagates over is the solve's free parameters (internal units: radians), then
    the re-calibrated markers' coordinates, then the other markers' coordinates (independent, with
    their calibration σ).
    """

    model: Model
    xm0: Array  # the full model vector at the solution
    names: list[str]  # one per column of ``cov``
    x0: Array  # their values
    model_index: Array  # model-vector index of each of the first len(model_index) columns
    marker_col: dict[str, int]  # marker → first of its three columns
    cov: Array
    photos_of: dict[str, list[str]] = field(default_factory=dict)  # node or marker → photos marking it
    recalibrated: bool = False
    variance_factor: float = 1.0
    calibration_distances: list[dict[str, Any]] = field(default_factory=list)
    where: str = ""  # the project file, for messages
    unit: LengthUnit = METRES  # the project's unit of lengths, for messages (vebuild.project.units)

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def build(cls, model: Model, names: Sequence[str], values: Array, cov: Array, model_index: Sequence[int],
              markers: Mapping[str, Array], marker_cov_names: Sequence[str] = (),
              marker_sigma: Mapping[str, Array] | None = None, **kw: Any) -> SolvedModel:
        """From the model's solved parameters (their names, values, covariance and model-vector indices)
        followed by the re-calibrated markers (``marker_cov_names``, three columns each), plus the
        other ``markers`` with independent ``marker_sigma`` (default 0: exact)."""
        n = len(names)
        others = [m for m in sorted(markers) if m not in set(marker_cov_names)]
        sig = np.concatenate([np.asarray((marker_sigma or {}).get(m, np.zeros(3)), float) for m in others]
                             or [np.zeros(0)])
        full = np.zeros((n + 3 * len(others),) * 2)
        full[:n, :n] = cov
        full[n:, n:] = np.diag(sig**2)
        marker_col = {m: len(model_index) + 3 * i for i, m in enumerate(marker_cov_names)}
        marker_col.update({m: n + 3 * i for i, m in enumerate(others)})
        x0 = np.concatenate([np.asarray(values, float), *[np.asarray(markers[m], float) for m in others]])
        names = list(names) + [f"marker:{m}.{c}" for m in others for c in "xyz"]
        return cls(model, model.vector(), names, x0, np.asarray(model_index, int), marker_col, full, **kw)

    @classmethod
    def from_problem(cls, problem: Any, solution: Any, marker_sigma: Mapping[str, Array] | None = None
                     ) -> SolvedModel:
        """From a :class:`~vebuild.model.solver.Problem` and its ``solution`` (tests, benchmarks)."""
        model = problem.model
        model.set_vector(problem.model_vector(solution.x))
        keep = problem.layout.model_and_markers()
        names = [n for b in (problem.layout.model, *problem.layout.markers.values()) for n in b.names]
        photos: dict[str, set[str]] = {}
        for p in problem.pins:
            photos.setdefault(p.node, set()).add(p.photo)
        return cls.build(model, names, solution.x[keep], solution.covariance[np.ix_(keep, keep)], problem.free_idx,
                         solution.markers, problem.free_markers, marker_sigma,
                         photos_of={k: sorted(v) for k, v in photos.items()},
                         recalibrated=problem.recalibrate, variance_factor=solution.variance_factor)

    @classmethod
    def from_project(cls, project: Project) -> SolvedModel:
        """From a solved project: ``model.nodes`` (the solved values) and ``model_solution.covariance``,
        decoded by :func:`vebuild.project.decode.solution`."""
        from vebuild.project import decode

        decode.require_solution(project)
        check_model_solution(project)
        s = decode.solution(project)
        return cls.build(s.model, s.names, s.values, s.covariance, s.model_index, s.markers, s.solved_markers,
                         s.marker_sigma, photos_of=s.photos_of, recalibrated=s.recalibrated,
                         variance_factor=s.variance_factor, calibration_distances=s.calibration_distances,
                         where=str(project.path), unit=length_unit(project.data))

    # -- evaluation -----------------------------------------------------------------------------
    def _state(self, x: Array) -> tuple[Array, Mapping[str, Array]]:
        """The model vector at x and its nodes' world transforms, each computed when first asked
        for: a measurement's difference quotients ask for a few nodes of hundreds."""
        xm = self.xm0.copy()
        xm[self.model_index] = x[: len(self.model_index)]
        return xm, self.model.lazy_world_transforms(xm)

    def marker_position(self, name: str, x: Array | None = None) -> Array:
        x = self.x0 if x is None else x
        o = self.marker_col[name]
        return x[o : o + 3]

    def world(self, point: Point, x: Array | None = None, state: tuple | None = None) -> Array:
        """World position of ``point`` at parameter vector ``x`` (default: the solution)."""
        x = self.x0 if x is None else x
        if point.kind == "marker":
            assert point.marker is not None
            return self.marker_position(point.marker, x).copy()
        xm, T = state or self._state(x)
        assert point.node is not None
        prim = self.model.node(point.node).primitive
        assert prim is not None  # handles and surface points are on primitives
        params = xm[self.model.slices[point.node][1]]
        if point.kind == "handle":
            local = prim.handles(params)[prim.handle_names().index(point.handle)]
        else:
            assert point.coords is not None
            local = from_coords(prim, params, np.asarray(point.coords, float))
        return T[point.node][:3, :3] @ local + T[point.node][:3, 3]

    def column_owner(self, j: int) -> str:
        """The node (or ``marker:NAME``) whose parameter column j is."""
        name = self.names[j]
        if name.startswith("marker:"):
            return name.rsplit(".", 1)[0]
        return name.rsplit(".", 1)[0]
