"""Measuring and marking by clicking, for both windows (the modelling screen and the walk-through):
what a click on a surface means, with no GL here.

A click gives a node and a world point (the walk-through's one-pixel ID buffer) or a pixel of a
calibrated photo (the modelling screen). Either becomes a **surface point reference** of the kind
``vebuild analyse`` parses, ``node@face:s,t`` (s, t metres from the face's centre along its axes,
:mod:`vebuild.analysis.points`), rounded to :data:`ST_DECIMALS` decimals; the measurement is then
the command line's own request (:mod:`vebuild.analysis.requests`) run on those words, so a
clicked distance and ``vebuild analyse PROJECT distance A B`` agree to the last digit. What is
measured is saved as the project's ``analyses`` (the words of that command), which the report
runs again.

Evidence markers placed by a click are records of ``evidence_markers`` (added by
:func:`vebuild.analysis.markers.add_marker`, as ``vebuild mark`` does); a trajectory from two
clicked holes is a ``trajectory`` analysis whose holes' 1σ comes from the solve (their 3-D
position covariance), so its cone is the solve's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import VebuildError

if TYPE_CHECKING:
    from vebuild.analysis.requests import AnalysisResult, Request
    from vebuild.analysis.solved import SolvedModel
    from vebuild.project import Project

Array = NDArray[np.float64]

#: The kinds of measurement the measure tool cycles through.
MEASURES = ("distance", "height", "dimension")
#: Clicks each kind needs.
CLICKS = {"distance": 2, "height": 1, "dimension": 1, "trajectory": 2}
#: Decimals of the face coordinates s, t written in a reference (metres: 0.1 mm).
ST_DECIMALS = 4
#: Decimals of a trajectory's holes (X,Y,Z metres) and of its hole σ.
XYZ_DECIMALS = 4
#: Decimals of a trajectory's direction (degrees).
ANGLE_DECIMALS = 2
#: A click within this many pixels of a marker's pin removes it (the marker tool).
MARKER_PICK_PX = 10.0
#: A world point farther than this from every face of the picked node is not on it (metres).
ON_FACE_M = 0.02


class ClickError(VebuildError):
    """A click that cannot be measured or marked; its text is a sentence for the screen."""


@dataclass(frozen=True)
class Clicked:
    """A clicked point: its reference as ``vebuild analyse`` writes points, the node and face it
    lies on, and its world position (metres)."""

    reference: str
    node: str
    face: str
    world: Array


@dataclass
class Measured:
    """One measurement made by clicks: the request run, its result (the command line's own table
    and figures), the saved record's words, the short ``label`` drawn in the view, and the world
    points to draw: a line from ``points[0]`` to ``points[1]`` (one point: a label there). A
    measurement on one photo alone (:mod:`.click_single_view`) has ``photo`` and the ``pixels``
    clicked on it instead of world points."""

    kind: str
    request: Request
    result: AnalysisResult
    command: list[str]
    label: str
    points: list[Array] = field(default_factory=list)
    name: str = ""
    photo: str | None = None
    pixels: list[Array] = field(default_factory=list)


def solved_model(project: Project) -> SolvedModel:
    """The solved model the analyses read (an unsolved project is a clear error)."""
    from vebuild.analysis.solved import SolvedModel

    try:
        return SolvedModel.from_project(project)
    except VebuildError as e:
        raise ClickError(f"measuring needs a solved model: {e}") from None


def _face_frame(prim: Any, mesh: Any, face: str) -> tuple[Array, Array, Array]:
    """The origin and axes of a flat face, as :func:`vebuild.analysis.points.face_point` takes them."""
    if face in prim.faces():
        o, x, y, _ = prim.face_frame(face)
        return np.asarray(o, float), np.asarray(x, float), np.asarray(y, float)
    fid = mesh.face_names.index(face) + 1
    tris = mesh.faces[mesh.face_ids == fid]
    V = mesh.vertices
    o = V[np.unique(tris)].mean(axis=0)
    n = np.cross(V[tris[0, 1]] - V[tris[0, 0]], V[tris[0, 2]] - V[tris[0, 0]])
    n /= np.linalg.norm(n)
    x = np.cross([0.0, 0.0, 1.0], n)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
    return o, x, np.cross(n, x)


def _nearest_face(mesh: Any, local: Array) -> tuple[str, float]:
    """The face of a mesh nearest a point (primitive coordinates) and its distance."""
    V, F = mesh.vertices, mesh.faces
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    # Closest point on each triangle (Ericson, Real-Time Collision Detection 5.1.5), vectorised
    # through the barycentric clamp of the projection onto the triangle's plane and its edges.
    best = np.full(len(F), np.inf)
    n = np.cross(b - a, c - a)
    nn = np.maximum((n * n).sum(1), 1e-30)
    w = local - a
    plane = (w * n).sum(1) / nn
    p = local - plane[:, None] * n
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = np.maximum(d00 * d11 - d01 * d01, 1e-30)
    bv = (d11 * d20 - d01 * d21) / den
    bw = (d00 * d21 - d01 * d20) / den
    inside = (bv >= -1e-9) & (bw >= -1e-9) & (bv + bw <= 1 + 1e-9)
    best[inside] = np.abs(plane[inside]) * np.sqrt(nn[inside])
    for p0, p1 in ((a, b), (b, c), (c, a)):  # the edges, for a point beside every triangle
        e = p1 - p0
        t = np.clip(((local - p0) * e).sum(1) / np.maximum((e * e).sum(1), 1e-30), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(local - (p0 + t[:, None] * e), axis=1))
    k = int(np.argmin(best))
    return mesh.face_names[mesh.face_ids[k] - 1], float(best[k])


def surface_reference(solved: SolvedModel, node: str, world: Any, face: str | None = None) -> Clicked:
    """The reference ``node@face:s,t`` of a world point on a flat face of ``node`` (``face``: the
    face it lies on, if known; else the face nearest the point)."""
    from vebuild.analysis.points import PICK_SEGMENTS, face_point
    from vebuild.model.scene import ModelError

    try:
        n = solved.model.node(node)
    except (VebuildError, ModelError):
        raise ClickError(f"'{node}' is not a node of the solved model; solve the model again") from None
    if n.primitive is None:
        raise ClickError(f"'{node}' is a group with no surface of its own")
    prim = n.primitive
    mesh = prim.mesh(segments=PICK_SEGMENTS)
    _, T = solved._state(solved.x0)
    inv = np.linalg.inv(T[node])
    X = np.asarray(world, float)
    local = inv[:3, :3] @ X + inv[:3, 3]
    if face is not None and face not in mesh.face_names:
        raise ClickError(f"a {prim.TYPE} has no face '{face}'")
    if face is None:
        face, dist = _nearest_face(mesh, local)
        if dist > ON_FACE_M:
            raise ClickError(f"the point clicked is {dist:.3f} m from every face of '{node}'")
    try:
        o, x, y = _face_frame(prim, mesh, face)
    except ValueError:  # a curved face has no frame
        raise ClickError(f"'{node}@{face}' is curved: click a flat face (or measure the object's dimensions)") from None
    s, t = round(float((local - o) @ x), ST_DECIMALS), round(float((local - o) @ y), ST_DECIMALS)
    ref = f"{node}@{face}:{s:.{ST_DECIMALS}f},{t:.{ST_DECIMALS}f}"
    try:
        point = face_point(solved, node, face, s, t, ref)  # the command line's own reading of it
    except VebuildError as e:
        raise ClickError(str(e)) from None
    return Clicked(ref, node, face, solved.world(point))


def photo_reference(project: Project, solved: SolvedModel, photo: str, uv: Any) -> Clicked:
    """The surface point seen at pixel ``uv`` of a calibrated photo (the command line's
    ``photo:ID@u,v`` pick), as a ``node@face:s,t`` reference."""
    from vebuild.analysis.points import parse_point
    from vebuild.project.decode import find_view, photo_camera

    def resolve(kind: str, name: str) -> Any:
        return photo_camera(project, name) if kind == "photo" else find_view(project, name)

    text = f"photo:{photo}@{float(uv[0]):.2f},{float(uv[1]):.2f}"
    try:
        p = parse_point(text, solved, resolve_camera=resolve)
    except VebuildError as e:
        raise ClickError(str(e)) from None
    assert p.node is not None and p.face is not None  # a pick is a surface point
    return surface_reference(solved, p.node, solved.world(p), p.face)


# -- measurements ------------------------------------------------------------------------------------

def _request(kind: str, clicks: list[Clicked]) -> tuple[Request, list[str]]:
    from vebuild.analysis.requests import DimensionsRequest, DistanceRequest, HeightRequest

    if len(clicks) != CLICKS[kind]:
        raise ClickError(f"a {kind} needs {CLICKS[kind]} clicked point{'s' if CLICKS[kind] > 1 else ''}")
    if kind == "distance":
        return DistanceRequest(clicks[0].reference, clicks[1].reference), ["distance", clicks[0].reference,
                                                                           clicks[1].reference]
    if kind == "height":
        return HeightRequest(clicks[0].reference), ["height", clicks[0].reference]
    return DimensionsRequest((clicks[0].node,)), ["dimensions", clicks[0].node]


def figure_text(m: dict[str, Any], unit: str = "m") -> str:
    """One measurement's figures as the command line's table prints them: the value, its 1σ and
    95 % interval (metres, 1σ in mm; or relative units)."""
    if unit == "relative":
        v, s, (lo, hi) = m["value_relative"], m["sigma_relative"], m["ci95_relative"]
        return f"{v:.4f} rel. (1σ {s:.4f}, 95 % [{lo:.4f}, {hi:.4f}])"
    v, s, ci = m["value_m"], m["sigma_m"], m["ci95_m"]
    if s is None or m.get("entered_sigma") == 0:
        return f"{v:.4f} m (held as entered, no 1σ)"
    return f"{v:.4f} m (1σ {1000 * s:.2f} mm, 95 % [{ci[0]:.4f}, {ci[1]:.4f}] m)"


def measure(project: Project, kind: str, clicks: list[Clicked]) -> Measured:
    """Run the measurement ``kind`` (:data:`MEASURES`) on the clicked points: the command line's
    request on their references."""
    if kind not in MEASURES:
        raise ClickError(f"no measurement '{kind}'; the measurements are {', '.join(MEASURES)}")
    request, command = _request(kind, clicks)
    result = request.run(project)
    unit = result.figures.get("lengths", "m")
    rows = result.figures["measurements"]
    if kind == "dimension":
        label = "; ".join(f"{r['what']} {figure_text(r, unit)}" for r in rows)
        points = [clicks[0].world]
    else:
        label = f"{kind} {figure_text(rows[0], unit)}"
        P = clicks[0].world
        points = [c.world for c in clicks] if kind == "distance" else [P, np.array([P[0], P[1], 0.0])]
    return Measured(kind, request, result, command, label, points)


def direction_angles(direction: Any) -> tuple[float, float]:
    """Azimuth (degrees counter-clockwise from +X about +Z) and elevation (above the horizontal)
    of a direction, rounded to :data:`ANGLE_DECIMALS`."""
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    return (round(math.degrees(math.atan2(d[1], d[0])), ANGLE_DECIMALS),
            round(math.degrees(math.asin(float(np.clip(d[2], -1.0, 1.0)))), ANGLE_DECIMALS))


def hole_sigma(solved: SolvedModel, clicked: Clicked) -> float:
    """The isotropic 1σ of a clicked hole's position from the solve: the RMS of its three
    coordinates' 1σ (metres)."""
    from vebuild.analysis.measure import propagate
    from vebuild.analysis.points import parse_point

    p = parse_point(clicked.reference, solved)
    est = propagate(solved, lambda x: solved.world(p, x))
    return float(np.sqrt(np.mean(np.asarray(est.sigma, float) ** 2)))


def trajectory(project: Project, entry: Clicked, exit: Clicked | None = None,
               direction: Any = None) -> Measured:
    """The trajectory from a clicked entry hole to a clicked exit hole (its cone from the holes'
    1σ in the solve) or along ``direction`` from the entry hole (no cone: no σ for a direction)."""
    from vebuild.analysis.requests_geometry import TrajectoryRequest

    def xyz(c: Clicked) -> str:
        return ",".join(f"{float(v):.{XYZ_DECIMALS}f}" for v in c.world)

    if (exit is None) == (direction is None):
        raise ClickError("a trajectory needs an exit hole or a direction")
    command = ["trajectory", "--from", xyz(entry)]
    from vebuild.project.units import length_unit

    if exit is not None and length_unit(project.data).relative:
        request = TrajectoryRequest(xyz(entry), to=xyz(exit))  # no hole σ in relative units
        command += ["--to", xyz(exit)]
    elif exit is not None:
        solved = solved_model(project)
        sa, sb = hole_sigma(solved, entry), hole_sigma(solved, exit)
        sig = f"{sa:.{XYZ_DECIMALS + 1}f},{sb:.{XYZ_DECIMALS + 1}f}"
        request = TrajectoryRequest(xyz(entry), to=xyz(exit), sigma=sig if sa + sb > 0 else None)
        command += ["--to", xyz(exit)] + (["--sigma", sig] if sa + sb > 0 else [])
    else:
        az, el = direction_angles(direction)
        request = TrajectoryRequest(xyz(entry), azimuth=az, elevation=el)
        command += ["--azimuth", f"{az:g}", "--elevation", f"{el:g}"]
    result = request.run(project)
    fig = result.figures.get("trajectory", result.figures)
    cone, stop = fig.get("cone_half_angle_95_deg"), fig.get("stops_at")
    label = ("trajectory" + (f", stops at {stop['node']} ({stop['face']})" if stop else ", leaves the scene")
             + (f", cone half-angle {cone:.3f}° (95 %)" if cone else ""))
    pts = [entry.world] + ([exit.world] if exit is not None else [])
    return Measured("trajectory", request, result, command, label, pts)


# -- what is saved -------------------------------------------------------------------------------------

def analysis_record(data: dict[str, Any], measured: Measured) -> dict[str, Any]:
    """The ``analyses`` record of a measurement, its name the next free "clicked KIND N"."""
    names = {r["name"] for r in data.get("analyses") or []}
    n = 1
    while f"clicked {measured.kind} {n}" in names:
        n += 1
    measured.name = f"clicked {measured.kind} {n}"
    return {"name": measured.name, "description": measured.label, "command": list(measured.command)}


def save_analysis(data: dict[str, Any], measured: Measured) -> dict[str, Any]:
    """Append the measurement to the document's ``analyses`` (the caller saves the file)."""
    rec = analysis_record(data, measured)
    data["analyses"] = list(data.get("analyses") or []) + [rec]
    return rec


def next_marker_label(data: dict[str, Any]) -> str:
    """The next free evidence marker label: E1, E2, …"""
    labels = {m["label"] for m in data.get("evidence_markers") or []}
    n = 1
    while f"E{n}" in labels:
        n += 1
    return f"E{n}"


def place_marker(data: dict[str, Any], node: str, world: Any, label: str | None = None) -> dict[str, Any]:
    """An evidence marker at a clicked surface point, added to the document (as ``vebuild mark``)."""
    from vebuild.analysis.markers import MAX_COORDINATE_M, add_marker

    X = [float(v) for v in world]
    if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE_M for v in X):
        raise ClickError(f"the clicked point {X} is not a place for a marker")
    rec = {"label": label or next_marker_label(data), "position": [round(v, 6) for v in X], "node": node}

    add_marker(SimpleNamespace(data=data), rec)  # type: ignore[arg-type]  # it reads and writes only the data
    return rec


def marker_near(data: dict[str, Any], pixels: list[tuple[str, float, float]], uv: Any,
                radius: float = MARKER_PICK_PX) -> str | None:
    """The label of the marker whose pin (``pixels``: label, u, v as drawn) is nearest ``uv``,
    within ``radius`` pixels; None if none."""
    best: tuple[float, str] | None = None
    for label, u, v in pixels:
        d = math.hypot(u - float(uv[0]), v - float(uv[1]))
        if d <= radius and (best is None or d < best[0]):
            best = (d, label)
    return best[1] if best else None


def remove_marker(data: dict[str, Any], label: str) -> None:
    """Remove a marker by label (as ``vebuild mark --remove``)."""
    markers = data.get("evidence_markers") or []
    if label not in [m["label"] for m in markers]:
        raise ClickError(f"no evidence marker is labelled {label!r}")
    data["evidence_markers"] = [m for m in markers if m["label"] != label]

