"""Measurements with uncertainty: distances, heights, dimensions and check distances (paper §5.1).

A point is tied to the model, so that its world position is a function of the solved parameters:

- a handle, ``node:handle`` (a box's corner ``cabinet:v4``);
- a point on a face of a primitive, ``node@face:s,t``: s, t metres from the face's centre along
  the face's x and y axes (a restable face's frame, as for ``rests_on``; on a side face x runs
  horizontally, to the right seen from outside, and y up the face); ``node@face`` is its centre;
- a pixel of a photo or a named view, ``photo:ID@u,v`` or ``view:NAME@u,v``: the first surface of
  the model that the pixel's ray meets (pixel convention of DESIGN.md: u right, v down, origin at
  the image's top-left corner);
- a marker's name (``T2``).

A point on a face is kept in *normalised* local coordinates of its primitive (x / width, y / depth,
z / height for a box; the angle and height fraction on a cylinder or frustum; the direction from a
sphere's centre), fixed when the point is placed: when a parameter changes, the point stays at the
same place on the face, the face scaled with it.

Uncertainty. ``vebuild solve`` stores the joint covariance of the model's parameters (and, when it
re-calibrated, of the markers) in ``model_solution.covariance``; a measurement's 1σ is propagated
linearly, σ² = J Σ Jᵀ, with J by central finite differences over that parameter vector, so the
correlations between parameters (two corners of one box) are accounted for. Markers that the solve
did not re-calibrate enter with their calibration 1σ per axis, independent of the model and of
each other (the calibration stores no cross-covariance). A check distance between two such markers
uses the calibration's own figure, which was propagated from its full covariance. The 95 %
interval is value ± 1.96 σ. :func:`monte_carlo` samples the same Gaussian to verify the linear
propagation.

Layer 6 of DESIGN.md: numpy only, no GL (a pixel's ray is intersected with the primitives' meshes
here rather than through the renderer's ID buffer).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..camera import pixel_rays_world
from ..errors import ProjectError, VebuildError
from ..model.primitives import Primitive, Sphere, _Round
from ..model.scene import Model, ModelError

Array = NDArray[np.float64]

Z95 = 1.959964  # two-sided 95 % of a Gaussian
#: Relative finite-difference step of the measurement Jacobian (central differences).
FD_STEP = 1e-6
#: Facets around curved surfaces when a pixel's ray is intersected with the model.
PICK_SEGMENTS = 32
ANGLE_DOFS = ("yaw", "angle", "wx", "wy", "wz")
POINT_SYNTAX = ("node:handle, node@face:s,t (metres from the face's centre), node@face, photo:ID@u,v, "
                "view:NAME@u,v, or a marker's name")


class MeasureError(VebuildError):
    """A point, node, face or handle that does not exist, or a point off every surface."""


# ----------------------------------------------------------------------------------------------
# Points


def check_model_solution(project: Any) -> None:
    """``model_solution`` fits the model: its nodes are nodes of ``model.nodes``, and its covariance
    matrix is square with one row and one column per entry of its parameter list.

    Raises ProjectError naming the file and the JSON path (nothing to check if the project has not
    been solved).
    """
    from ..project import json_path

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
    coords: tuple[float, float, float] | None = None
    marker: str | None = None


def to_coords(prim: Primitive, local: Array, snap_face: str | None = None) -> Array:
    """Normalised coordinates of a local point on ``prim`` at its own parameters (see the module).

    ``snap_face``: put a point of a faceted curved surface (a pick on the mesh) onto the true one.
    """
    p = prim.params
    local = np.asarray(local, float)
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
        o = problem.n_model + problem.n_cam * len(problem.cam_ids)
        keep = np.r_[np.arange(problem.n_model), np.arange(o, o + 3 * len(problem.free_markers))].astype(int)
        names = list(problem.names) + [f"marker:{m}.{c}" for m in problem.free_markers for c in "xyz"]
        photos: dict[str, set[str]] = {}
        for p in problem.pins:
            photos.setdefault(p.node, set()).add(p.photo)
        return cls.build(model, names, solution.x[keep], solution.covariance[np.ix_(keep, keep)], problem.free_idx,
                         solution.markers, problem.free_markers, marker_sigma,
                         photos_of={k: sorted(v) for k, v in photos.items()},
                         recalibrated=problem.recalibrate, variance_factor=solution.variance_factor)

    @classmethod
    def from_project(cls, project: Any) -> SolvedModel:
        """From a solved project: ``model.nodes`` (the solved values) and ``model_solution.covariance``,
        decoded by :func:`vebuild.project.decode.solution`."""
        from ..project import decode

        decode.require_solution(project)
        check_model_solution(project)
        s = decode.solution(project)
        return cls.build(s.model, s.names, s.values, s.covariance, s.model_index, s.markers, s.solved_markers,
                         s.marker_sigma, photos_of=s.photos_of, recalibrated=s.recalibrated,
                         variance_factor=s.variance_factor, calibration_distances=s.calibration_distances,
                         where=str(project.path))

    # -- evaluation -----------------------------------------------------------------------------
    def _state(self, x: Array) -> tuple[Array, dict[str, Array]]:
        xm = self.xm0.copy()
        xm[self.model_index] = x[: len(self.model_index)]
        return xm, self.model.world_transforms(xm)

    def marker_position(self, name: str, x: Array | None = None) -> Array:
        x = self.x0 if x is None else x
        o = self.marker_col[name]
        return x[o : o + 3]

    def world(self, point: Point, x: Array | None = None, state: tuple | None = None) -> Array:
        """World position of ``point`` at parameter vector ``x`` (default: the solution)."""
        x = self.x0 if x is None else x
        if point.kind == "marker":
            return self.marker_position(point.marker, x).copy()
        xm, T = state or self._state(x)
        node = self.model.node(point.node)
        params = xm[self.model.slices[point.node][1]]
        if point.kind == "handle":
            local = node.primitive.handles(params)[node.primitive.handle_names().index(point.handle)]
        else:
            local = from_coords(node.primitive, params, point.coords)
        return T[point.node][:3, :3] @ local + T[point.node][:3, 3]

    def column_owner(self, j: int) -> str:
        """The node (or ``marker:NAME``) whose parameter column j is."""
        name = self.names[j]
        if name.startswith("marker:"):
            return name.rsplit(".", 1)[0]
        return name.rsplit(".", 1)[0]


# ----------------------------------------------------------------------------------------------
# Propagation


@dataclass
class Estimate:
    """Values (m,) with their covariance (m, m) and what they rest on."""

    value: Array
    cov: Array
    nodes: list[str]
    markers: list[str]
    photos: list[str]

    @property
    def sigma(self) -> Array:
        return np.sqrt(np.maximum(np.diag(self.cov), 0.0))


def propagate(solved: SolvedModel, f: Callable[[Array], Array]) -> Estimate:
    """Linear propagation of the parameters' covariance through f (x → (m,)): J Σ Jᵀ, J by central
    differences over the columns that have any variance."""
    x0 = solved.x0
    v0 = np.atleast_1d(np.asarray(f(x0), float))
    d = np.diag(solved.cov)
    cols = np.flatnonzero(d != 0)
    J = np.zeros((len(v0), len(x0)))
    for j in cols:
        h = FD_STEP * max(1.0, abs(x0[j]))
        xp, xn = x0.copy(), x0.copy()
        xp[j] += h
        xn[j] -= h
        J[:, j] = (np.atleast_1d(f(xp)) - np.atleast_1d(f(xn))) / (2 * h)
    used = np.flatnonzero(np.any(J != 0, axis=0))
    Ju = J[:, used]
    C = solved.cov[np.ix_(used, used)]
    if np.all(np.isfinite(C)):
        cov = Ju @ C @ Ju.T
    else:
        cov = np.full((len(v0), len(v0)), np.inf)
    owners = sorted({solved.column_owner(j) for j in used})
    nodes = [o for o in owners if not o.startswith("marker:")]
    markers = [o[len("marker:"):] for o in owners if o.startswith("marker:")]
    photos = sorted({p for o in owners for p in solved.photos_of.get(o, [])})
    return Estimate(v0, cov, nodes, markers, photos)


def monte_carlo(solved: SolvedModel, f: Callable[[Array], Array], n: int = 2000,
                rng: np.random.Generator | None = None) -> tuple[Array, Array]:
    """Mean and covariance of f over ``n`` samples of the parameters ~ N(x0, Σ) (checks ``propagate``)."""
    rng = np.random.default_rng(0) if rng is None else rng
    w, V = np.linalg.eigh(0.5 * (solved.cov + solved.cov.T))
    L = V * np.sqrt(np.maximum(w, 0.0))
    samples = solved.x0 + rng.standard_normal((n, len(solved.x0))) @ L.T
    vals = np.array([np.atleast_1d(f(x)) for x in samples])
    return vals.mean(axis=0), np.atleast_2d(np.cov(vals, rowvar=False))


# ----------------------------------------------------------------------------------------------
# Measurements


@dataclass
class Measurement:
    """One measured quantity: value, 1σ and 95 % interval (metres), and what it rests on."""

    quantity: str  # "distance", "height", "dimension"
    what: str  # e.g. "cabinet:v4 to box:v0"
    value: float
    sigma: float
    nodes: list[str] = field(default_factory=list)
    markers: list[str] = field(default_factory=list)
    photos: list[str] = field(default_factory=list)
    points: list[dict[str, Any]] = field(default_factory=list)
    source: str = "model solution"

    @property
    def ci95(self) -> tuple[float, float]:
        return (self.value - Z95 * self.sigma, self.value + Z95 * self.sigma)

    def to_json(self) -> dict[str, Any]:
        finite = bool(np.isfinite(self.sigma))
        return {"quantity": self.quantity, "what": self.what, "value_m": float(self.value),
                "sigma_m": float(self.sigma) if finite else None,
                "ci95_m": [float(v) for v in self.ci95] if finite else None,
                "source": self.source, "points": self.points,
                "rests_on": {"nodes": self.nodes, "markers": self.markers, "photos": self.photos}}


def _measurement(quantity: str, what: str, est: Estimate, k: int = 0, points: list | None = None) -> Measurement:
    return Measurement(quantity, what, float(est.value[k]), float(est.sigma[k]), est.nodes, est.markers, est.photos,
                       points or [])


def _point_record(solved: SolvedModel, p: Point) -> dict[str, Any]:
    rec: dict[str, Any] = {"point": p.label, "kind": p.kind, "position_m": [float(v) for v in solved.world(p)]}
    for k in ("node", "handle", "face", "marker"):
        if getattr(p, k) is not None:
            rec[k] = getattr(p, k)
    return rec


def distance(solved: SolvedModel, a: Point, b: Point) -> Measurement:
    """The straight-line distance between two points, metres."""
    def f(x: Array) -> Array:
        st = solved._state(x)
        return np.array([np.linalg.norm(solved.world(a, x, st) - solved.world(b, x, st))])

    return _measurement("distance", f"{a.label} to {b.label}", propagate(solved, f), 0,
                        [_point_record(solved, a), _point_record(solved, b)])


def distances(solved: SolvedModel, pairs: Sequence[tuple[Point, Point]]) -> Estimate:
    """Several distances at once, with their joint covariance (m, m)."""
    def f(x: Array) -> Array:
        st = solved._state(x)
        return np.array([np.linalg.norm(solved.world(a, x, st) - solved.world(b, x, st)) for a, b in pairs])

    return propagate(solved, f)


def height(solved: SolvedModel, point: Point, above: tuple[str, str] | None = None) -> Measurement:
    """Height of a point above the floor (its z; the floor is z = 0), or above the flat face
    ``above = (node, face)``: the signed distance to that face's plane along its outward normal."""
    if above is None:
        def f(x: Array) -> Array:
            return solved.world(point, x)[2:3]
        what = f"{point.label} above the floor (z = 0)"
    else:
        plane = _face_plane_points(solved, *above)

        def f(x: Array) -> Array:
            st = solved._state(x)
            P = np.array([solved.world(q, x, st) for q in plane])
            n = np.cross(P[1] - P[0], P[2] - P[0])
            n /= np.linalg.norm(n)
            return np.array([(solved.world(point, x, st) - P.mean(axis=0)) @ n])
        what = f"{point.label} above {above[0]}@{above[1]}"
    return _measurement("height", what, propagate(solved, f), 0, [_point_record(solved, point)])


def dimensions(solved: SolvedModel, node: str) -> list[Measurement]:
    """An object's dimensions: its primitive's parameters (width, depth, height, radius …); for a
    group, the extent of its parts' vertices along the group's own x, y, z (width, depth, height)."""
    n = _node(solved, node)
    if n.primitive is not None:
        sp = solved.model.slices[node][1]

        def f(x: Array) -> Array:
            return solved._state(x)[0][sp]
        est = propagate(solved, f)
        return [_measurement("dimension", f"{node}.{p}", est, k) for k, p in enumerate(n.primitive.PARAMS)]
    parts = [m for m in solved.model.subtree(node) if solved.model.node(m).primitive is not None]
    if not parts:
        raise MeasureError(f"node '{node}' is a group without primitives: it has no dimensions")

    def g(x: Array) -> Array:
        xm, T = solved._state(x)
        inv = np.linalg.inv(T[node])
        pts = []
        for m in parts:
            prim = solved.model.node(m).primitive
            h = prim.handles(xm[solved.model.slices[m][1]])
            W = h @ T[m][:3, :3].T + T[m][:3, 3]
            pts.append(W @ inv[:3, :3].T + inv[:3, 3])
        P = np.concatenate(pts)
        return P.max(axis=0) - P.min(axis=0)
    est = propagate(solved, g)
    return [_measurement("dimension", f"{node}.{p} (extent of its parts)", est, k)
            for k, p in enumerate(("width", "depth", "height"))]


# ----------------------------------------------------------------------------------------------
# Check distances


@dataclass
class CheckResult:
    """A known distance the solve did not use, against the model's measurement of it."""

    a: str
    b: str
    known: float
    known_sigma: float
    measured: Measurement

    @property
    def difference(self) -> float:
        return self.measured.value - self.known

    @property
    def difference_sigma(self) -> float:
        """1σ of the difference: the measurement's and the tape's, independent."""
        return float(np.hypot(self.measured.sigma, self.known_sigma))

    @property
    def within_ci95(self) -> bool:
        """Whether the difference lies within its 95 % interval (± 1.96 × ``difference_sigma``)."""
        return bool(abs(self.difference) <= Z95 * self.difference_sigma)

    def to_json(self) -> dict[str, Any]:
        m = self.measured.to_json()
        return {"a": self.a, "b": self.b, "known_m": self.known, "known_sigma_m": self.known_sigma,
                "measured_m": m["value_m"], "measured_sigma_m": m["sigma_m"], "measured_ci95_m": m["ci95_m"],
                "difference_m": self.difference, "difference_sigma_m": self.difference_sigma,
                "difference_ci95_m": [self.difference - Z95 * self.difference_sigma,
                                      self.difference + Z95 * self.difference_sigma],
                "within_ci95": self.within_ci95, "source": m["source"], "rests_on": m["rests_on"]}


def check_distances(project: Any, solved: SolvedModel) -> list[CheckResult]:
    """Every ``reference_distances`` entry of role ``check``, measured vs known."""
    out = []
    for i, d in enumerate(project.data.get("reference_distances", [])):
        if d["role"] != "check":
            continue
        ends = []
        for key in ("a", "b"):
            try:
                ends.append(parse_point(d[key], solved))
            except MeasureError as e:
                raise ProjectError(project.path, f"$.reference_distances[{i}].{key}", str(e)) from None
        a, b = ends
        m = distance(solved, a, b)
        if a.kind == b.kind == "marker" and not solved.recalibrated:
            # Neither marker was solved with the model: the calibration measured this distance from
            # its own full covariance (the markers' correlations, which it does not store).
            for c in solved.calibration_distances:
                if {c.get("a"), c.get("b")} == {d["a"], d["b"]} and c.get("measured") is not None:
                    m = Measurement("distance", m.what, float(c["measured"]), float(c["measured_sigma"]), [],
                                    [d["a"], d["b"]], m.photos, m.points, "calibration")
                    break
        out.append(CheckResult(d["a"], d["b"], float(d["distance"]), float(d.get("sigma", 0.002)), m))
    return out


# ----------------------------------------------------------------------------------------------
# Parsing points and picking


def _node(solved: SolvedModel, name: str):
    try:
        return solved.model.node(name)
    except ModelError:
        known = ", ".join(n.name for n in solved.model.nodes)
        raise MeasureError(f"no node named '{name}' in the model; the nodes are: {known}") from None


def _primitive_node(solved: SolvedModel, name: str, label: str):
    n = _node(solved, name)
    if n.primitive is None:
        parts = ", ".join(c for c in solved.model.subtree(name)[1:] if solved.model.node(c).primitive is not None)
        raise MeasureError(f"point '{label}': node '{name}' is a group with no surface of its own; name one of its "
                           f"parts ({parts or 'none'})")
    return n


def _numbers(text: str, label: str, what: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise MeasureError(f"point '{label}': expected {what} as two numbers 'A,B', got '{text}'") from None
    if not (np.isfinite(a) and np.isfinite(b)):
        raise MeasureError(f"point '{label}': {what} must be finite, got '{text}'")
    return a, b


def parse_point(text: str, solved: SolvedModel, cameras: Mapping[str, Any] | None = None,
                resolve_camera: Callable[[str, str], Any] | None = None) -> Point:
    """A point from its written form (see the module, and ``POINT_SYNTAX``).

    ``resolve_camera(kind, name)`` returns the :class:`~vebuild.camera.ImageCamera` of a photo
    (kind ``photo``) or a named view (kind ``view``) for pixel points.
    """
    text = text.strip()
    head = text.split(":", 1)[0]
    if head in ("photo", "view") and ":" in text and "@" in text.split(":", 1)[1]:
        name, uv = text.split(":", 1)[1].rsplit("@", 1)
        u, v = _numbers(uv, text, "a pixel u,v")
        if resolve_camera is None:
            raise MeasureError(f"point '{text}': pixel points need the project's cameras")
        try:
            cam = resolve_camera(head, name)
        except VebuildError as e:
            raise MeasureError(f"point '{text}': {e}") from None
        if not (0 <= u <= cam.width and 0 <= v <= cam.height):
            raise MeasureError(f"point '{text}': pixel ({u:g}, {v:g}) lies outside the {head}'s "
                               f"{cam.width}×{cam.height} image")
        return pick(solved, cam.K, cam.R, cam.C, (u, v), text)
    if "@" in text:
        node, rest = text.split("@", 1)
        face, _, st = rest.partition(":")
        s, t = _numbers(st, text, "face coordinates s,t (metres)") if st else (0.0, 0.0)
        return face_point(solved, node, face, s, t, text)
    if ":" in text:
        node, handle = text.rsplit(":", 1)
        prim = _primitive_node(solved, node, text).primitive
        if handle not in prim.handle_names():
            raise MeasureError(f"point '{text}': node '{node}' ({prim.TYPE}) has no handle '{handle}'; its handles "
                               f"are: {', '.join(prim.handle_names())}")
        return Point(text, "handle", node=node, handle=handle)
    if text in solved.marker_col:
        return Point(text, "marker", marker=text)
    raise MeasureError(f"point '{text}' is not a marker of the calibration; write a point as {POINT_SYNTAX}")


def _face_triangles(prim: Primitive, face: str, label: str) -> tuple[Any, Array]:
    mesh = prim.mesh(segments=PICK_SEGMENTS)
    if face not in mesh.face_names:
        raise MeasureError(f"point '{label}': a {prim.TYPE} has no face '{face}'; its faces are: "
                           f"{', '.join(mesh.face_names)}")
    fid = mesh.face_names.index(face) + 1
    return mesh, mesh.faces[mesh.face_ids == fid]


def _is_curved(prim: Primitive, face: str) -> bool:
    return (isinstance(prim, _Round) and face == "side") or isinstance(prim, Sphere)


def face_point(solved: SolvedModel, node: str, face: str, s: float, t: float, label: str | None = None) -> Point:
    """The point s, t metres from the centre of a flat ``face`` of ``node`` along the face's axes."""
    label = label or f"{node}@{face}:{s:g},{t:g}"
    prim = _primitive_node(solved, node, label).primitive
    mesh, tris = _face_triangles(prim, face, label)
    if _is_curved(prim, face):
        raise MeasureError(f"point '{label}': face '{face}' of a {prim.TYPE} is curved; give a handle or a pixel "
                           "of a photo instead of face coordinates")
    V = mesh.vertices
    if face in prim.faces():
        o, x, y, n = prim.face_frame(face)
    else:
        used = np.unique(tris)
        o = V[used].mean(axis=0)
        n = np.cross(V[tris[0, 1]] - V[tris[0, 0]], V[tris[0, 2]] - V[tris[0, 0]])
        n /= np.linalg.norm(n)
        x = np.cross([0.0, 0.0, 1.0], n)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
        y = np.cross(n, x)
    p = o + s * x + t * y
    if not _in_triangles(p, V, tris):
        size = mesh.chart_size_m[mesh.face_names.index(face)]
        raise MeasureError(f"point '{label}': ({s:g}, {t:g}) m from the centre of face '{face}' of '{node}' lies off "
                           f"that face ({size[0]:.3f} × {size[1]:.3f} m)")
    return Point(label, "surface", node=node, face=face, coords=tuple(float(c) for c in to_coords(prim, p)))


def _in_triangles(p: Array, V: Array, tris: Array, tol: float = 1e-9) -> bool:
    a, b, c = V[tris[:, 0]], V[tris[:, 1]], V[tris[:, 2]]
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return bool(np.any((v >= -tol) & (w >= -tol) & (v + w <= 1 + tol)))


def ray_hit(solved: SolvedModel, origin: Array, direction: Array) -> tuple[str, str, Array] | None:
    """The first surface a ray meets: (node, face name, world point), or None (Möller–Trumbore over
    every primitive's mesh, both sides of each triangle)."""
    xm, T = solved._state(solved.x0)
    best: tuple[float, str, str, Array] | None = None
    o, d = np.asarray(origin, float), np.asarray(direction, float)
    for node in solved.model.nodes:
        if node.primitive is None:
            continue
        mesh = node.primitive.mesh(segments=PICK_SEGMENTS)
        W = mesh.vertices @ T[node.name][:3, :3].T + T[node.name][:3, 3]
        a, b, c = W[mesh.faces[:, 0]], W[mesh.faces[:, 1]], W[mesh.faces[:, 2]]
        e1, e2 = b - a, c - a
        pv = np.cross(d, e2)
        det = (e1 * pv).sum(1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        sv = o - a
        u = (sv * pv).sum(1) * inv
        qv = np.cross(sv, e1)
        v = (qv @ d) * inv
        t = (qv * e2).sum(1) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
        if np.any(hit):
            k = np.flatnonzero(hit)[np.argmin(t[hit])]
            if best is None or t[k] < best[0]:
                best = (float(t[k]), node.name, mesh.face_names[mesh.face_ids[k] - 1], o + t[k] * d)
    return None if best is None else best[1:]


def pick(solved: SolvedModel, K: Array, R: Array, C: Array, uv: Sequence[float], label: str) -> Point:
    """The point of the model seen at pixel ``uv`` by the camera K, R, C; an error if its ray meets nothing."""
    d = pixel_rays_world(K, R, np.asarray(uv, float))
    hit = ray_hit(solved, np.asarray(C, float), d)
    if hit is None:
        raise MeasureError(f"point '{label}': the ray through pixel ({uv[0]:g}, {uv[1]:g}) meets no surface of the "
                           "model (it leaves through an opening or misses every object); pick a pixel on a surface")
    node, face, X = hit
    _, T = solved._state(solved.x0)
    inv = np.linalg.inv(T[node])
    local = inv[:3, :3] @ X + inv[:3, 3]
    prim = solved.model.node(node).primitive
    coords = to_coords(prim, local, snap_face=face if _is_curved(prim, face) else None)
    return Point(label, "surface", node=node, face=face, coords=tuple(float(c) for c in coords))


def _face_plane_points(solved: SolvedModel, node: str, face: str) -> list[Point]:
    """Three points of a flat face, tied to it (for a plane that moves with the parameters)."""
    label = f"{node}@{face}"
    prim = _primitive_node(solved, node, label).primitive
    mesh, tris = _face_triangles(prim, face, label)
    if _is_curved(prim, face):
        raise MeasureError(f"'{label}': face '{face}' of a {prim.TYPE} is curved; a height is measured above a flat "
                           "face")
    return [Point(label, "surface", node=node, face=face, coords=tuple(float(c) for c in to_coords(prim, p)))
            for p in mesh.vertices[tris[0]]]


__all__ = ["Z95", "POINT_SYNTAX", "MeasureError", "Point", "SolvedModel", "Estimate", "Measurement", "CheckResult",
           "propagate", "monte_carlo", "distance", "distances", "height", "dimensions", "check_distances",
           "parse_point", "face_point", "pick", "ray_hit", "to_coords", "from_coords"]
