"""Measurements with uncertainty: distances, heights, dimensions and check distances (paper §5.1).

Between points tied to the solved model (:mod:`vebuild.analysis.solved`, written as in
:mod:`vebuild.analysis.points`). A measurement's 1σ is propagated linearly from the solve's
covariance, σ² = J Σ Jᵀ, with J by central finite differences over the parameter vector, so the
correlations between parameters (two corners of one box) are accounted for. Markers that the solve
did not re-calibrate enter with their calibration 1σ per axis, independent of the model and of
each other (the calibration stores no cross-covariance). A check distance between two such markers
uses the calibration's own figure, which was propagated from its full covariance. The 95 %
interval is value ± Z95 σ (:data:`vebuild.constants.Z95`). :func:`monte_carlo` samples the same
Gaussian to verify the linear propagation.

Each measurement says which entered values it rests on (a node's ``hold``, FORMAT.md): a
dimension entered from a measurement with its 1σ (solved, its σ carried like any parameter's) or
held exactly (σ 0, carrying no uncertainty: the figure is then only as good as that entry). A
dimension that is itself entered is marked so (``entered``, ``entered_sigma``), never shown as a
perfect measurement.

Layer 6 of DESIGN.md: numpy only, no GL.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild.constants import Z95
from vebuild.errors import ProjectError
from vebuild.project.units import METRES, LengthUnit

from .points import face_plane_points, find_node, parse_point
from .solved import MeasureError, Point, SolvedModel

if TYPE_CHECKING:
    from vebuild.project import Project


Array = NDArray[np.float64]

#: Relative finite-difference step of the measurement Jacobian (central differences).
FD_STEP = 1e-6


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
    #: The entered values it depends on: ("node.param", its entered 1σ (0: held exactly), its unit:
    #: "m", or "deg" for an angle).
    entered: list[tuple[str, float, str]] = field(default_factory=list)

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
    owners = sorted({solved.column_owner(int(j)) for j in used})
    nodes = [o for o in owners if not o.startswith("marker:")]
    markers = [o[len("marker:"):] for o in owners if o.startswith("marker:")]
    photos = sorted({p for o in owners for p in solved.photos_of.get(o, [])})
    return Estimate(v0, cov, nodes, markers, photos, _entered_in(solved, f, v0, {solved.names[j] for j in used}))


def _entered_in(solved: SolvedModel, f: Callable[[Array], Array], v0: Array, used: set[str]
                ) -> list[tuple[str, float, str]]:
    """The entered values f depends on: a solved one (σ > 0) through its column, one held exactly
    (not a column) by moving it in the model vector."""
    out = []
    index = {n: i for i, n in enumerate(solved.model.parameter_names())}
    kinds = solved.model.parameter_kinds()
    for node in solved.model.nodes:
        for name in sorted({*node.hold, *(e.name for e in node.entered)}):
            full, sigma = f"{node.name}.{name}", node.entered_sigma(name)
            assert sigma is not None  # a held or entered name
            if full in solved.names:
                depends = full in used
            else:
                i = index[full]
                xm0 = solved.xm0
                try:
                    solved.xm0 = xm0.copy()
                    solved.xm0[i] += FD_STEP * max(1.0, abs(xm0[i]))
                    depends = bool(np.any(np.atleast_1d(f(solved.x0)) != v0))
                finally:
                    solved.xm0 = xm0
            if depends:
                out.append((full, sigma, "deg" if kinds[index[full]] == "angle" else "m"))
    return out


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
    #: The entered values it rests on: ("node.param", entered 1σ (0: held exactly), "m" or "deg").
    entered: list[tuple[str, float, str]] = field(default_factory=list)
    #: The measurement is itself an entered value, with this 1σ (None: it is not).
    entered_sigma: float | None = None

    @property
    def ci95(self) -> tuple[float, float]:
        return (self.value - Z95 * self.sigma, self.value + Z95 * self.sigma)

    def to_json(self, unit: LengthUnit = METRES) -> dict[str, Any]:
        """The figures, keyed with the project's unit of length (``value_m``, or ``value_relative``
        where its lengths are relative: :mod:`vebuild.project.units`)."""
        finite = bool(np.isfinite(self.sigma))
        points = [{(unit.key("position") if k == "position_m" else k): v for k, v in p.items()} for p in self.points]
        return {"quantity": self.quantity, "what": self.what, unit.key("value"): float(self.value),
                unit.key("sigma"): float(self.sigma) if finite else None,
                unit.key("ci95"): [float(v) for v in self.ci95] if finite else None,
                "source": self.source, "points": points,
                **({} if self.entered_sigma is None else {"entered": True, "entered_sigma": self.entered_sigma}),
                "rests_on": {"nodes": self.nodes, "markers": self.markers, "photos": self.photos,
                             "entered": [{"name": n, "entered_sigma": s, "unit": u} for n, s, u in self.entered]}}


def _measurement(quantity: str, what: str, est: Estimate, k: int = 0, points: list | None = None) -> Measurement:
    return Measurement(quantity, what, float(est.value[k]), float(est.sigma[k]), est.nodes, est.markers, est.photos,
                       points or [], entered=list(est.entered))


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
        plane = face_plane_points(solved, *above)

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
    n = find_node(solved, node)
    if n.primitive is not None:
        sp = solved.model.slices[node][1]

        def f(x: Array) -> Array:
            return solved._state(x)[0][sp]
        est = propagate(solved, f)
        out = []
        for k, p in enumerate(n.primitive.PARAMS):
            m = _measurement("dimension", f"{node}.{p}", est, k)
            m.entered_sigma = n.entered_sigma(p)  # the dimension itself entered (or None)
            m.entered = [] if m.entered_sigma is None else [(f"{node}.{p}", m.entered_sigma, "m")]
            out.append(m)
        return out
    parts = [m for m in solved.model.subtree(node) if solved.model.node(m).primitive is not None]
    if not parts:
        raise MeasureError(f"node '{node}' is a group without primitives: it has no dimensions")

    def g(x: Array) -> Array:
        xm, T = solved._state(x)
        inv = np.linalg.inv(T[node])
        pts = []
        for m in parts:
            prim = solved.model.node(m).primitive
            assert prim is not None  # parts are the nodes with primitives
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
    role: str = "check"  # the reference distance's role: "check" (not used by the solve) or "scale"

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

    @property
    def difference_ci95(self) -> tuple[float, float]:
        """The 95 % interval of the difference: difference ± 1.96 × ``difference_sigma``."""
        return (self.difference - Z95 * self.difference_sigma, self.difference + Z95 * self.difference_sigma)

    @property
    def verdict(self) -> str:
        """The check's verdict in words: whether the known distance lies within the 95 % interval of
        the measurement (the difference within ± 1.96 σ of zero)."""
        return "within the 95 % interval" if self.within_ci95 else "outside the 95 % interval"

    def to_json(self) -> dict[str, Any]:
        m = self.measured.to_json()
        return {"a": self.a, "b": self.b, "known_m": self.known, "known_sigma_m": self.known_sigma,
                "measured_m": m["value_m"], "measured_sigma_m": m["sigma_m"], "measured_ci95_m": m["ci95_m"],
                "difference_m": self.difference, "difference_sigma_m": self.difference_sigma,
                "difference_ci95_m": list(self.difference_ci95),
                "within_ci95": self.within_ci95, "verdict": self.verdict, "role": self.role,
                "source": m["source"], "rests_on": m["rests_on"]}


def check_distances(project: Project, solved: SolvedModel,
                    roles: Sequence[str] = ("check",)) -> list[CheckResult]:
    """Every ``reference_distances`` entry whose role is in ``roles`` (default: the check
    distances, which the solve did not use), measured on the final model against the known value.

    An end may be a marker or a model vertex (``node:handle``); a scale distance (``roles``
    including ``"scale"``) is measured the same way, though the solve was made to fit it, so its
    agreement is no independent check.
    """
    out = []
    for i, d in enumerate(project.data.get("reference_distances", [])):
        if d["role"] not in roles:
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
                if {c.get("a"), c.get("b")} == {d["a"], d["b"]} and c.get("measured") is not None \
                        and c.get("measured_sigma") is not None:
                    m = Measurement("distance", m.what, float(c["measured"]), float(c["measured_sigma"]), [],
                                    [d["a"], d["b"]], m.photos, m.points, "calibration")
                    break
        out.append(CheckResult(d["a"], d["b"], float(d["distance"]), float(d.get("sigma", 0.002)), m,
                               d["role"]))
    return out
