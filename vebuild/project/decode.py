"""The project document turned into domain objects: the one place that decodes it (layer 3).

Each part of the document is decoded here, once, and checked as it is decoded; every error is a
:class:`~vebuild.errors.ProjectError` (or, where the part is missing altogether, a
:class:`~vebuild.errors.VebuildError`) that names the file and the JSON path:

- cameras (decoded in :mod:`vebuild.project.cameras`, re-exported here): :func:`cameras` (the
  final ones: re-calibrated where solved so), :func:`camera_records`,
  :func:`cameras_from_calibration` (the calibration stage's: a re-calibration's priors; it refuses a
  project whose calibration an older vebuild overwrote, :func:`check_calibration_stage`),
  :func:`photo_camera` (one final camera, by id or position), :func:`view_camera` and
  :func:`find_view` (the named evidence views);
- markers: :func:`markers` (the ``{name: position}`` a stage needs: the calibration's, or
  ``"final"`` with the re-calibrated ones), :func:`marker_sigmas`, :func:`known_points` (the final
  markers and the solved model's vertices), :func:`sightings` (a photo's marker observations),
  :func:`reference_distances`, :func:`floor_markers`;
- a photo's own scale: :func:`photo_camera_height`, :func:`known_lengths`;
- a photo's marks for calibration: :func:`photo_marks` (vanishing segments or polylines, given focal
  length and principal point), :func:`vanishing_segments`;
- the model: :func:`model` (the scene graph, a ``ModelError`` :func:`located`), :func:`load_model`
  (with its pins and edge observations: :func:`pins_of`, :func:`edge_observations_of`),
  :func:`check_reference_handles`;
- the solution: :func:`solution` (the solved model with its covariance in code units);
- lighting: :func:`preset_from_record`, :func:`preset_names`, :func:`find_preset`;
- texture pages: :func:`texture_pages` (each atlas read, hash-checked and decoded once).

Writing goes the other way, through :mod:`vebuild.project.records` and :mod:`vebuild.project.file`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from vebuild.calibration.photo import FocalPrior
from vebuild.calibration.positions import ReferenceDistance
from vebuild.calibration.single_photo import CameraHeight, KnownLength
from vebuild.errors import ProjectError, VebuildError
from vebuild.lighting import (
    AS_PHOTOGRAPHED,
    AS_PHOTOGRAPHED_LIGHTING,
    DEFAULT_AMBIENT,
    DEFAULT_INNER_CONE_FRACTION,
    DEFAULT_OUTER_CONE_DEG,
    Light,
    Lighting,
)
from vebuild.model.residuals import EdgeObservation, Pin
from vebuild.model.scene import Model, ModelError, model_from_dict

from .camera_records import camera_records  # noqa: F401  (re-exported, as the cameras are)
from .cameras import (  # noqa: F401  (re-exported: decode is where every part of the document is decoded)
    DEFAULT_FOV_DEG,
    FRAME_35MM_WIDTH_MM,
    MAX_ABS_K1,
    ROTATION_TOLERANCE,
    cameras,
    cameras_from_calibration,
    check_calibration_stage,
    find_view,
    photo_camera,
    view_camera,
)
from .file import Project, decode_texture_page, read_texture_page, texture_page_path

Array = NDArray[np.float64]

# --------------------------------------------------------------------------------------------------
# Markers

MarkerSource = Literal["calibration", "final", "surveyed", "named", "joints"]


def markers(data: Mapping[str, Any], source: MarkerSource = "calibration") -> dict[str, Array]:
    """Marker positions by name, from the document ``data``:

    - ``"calibration"``: where the calibration stage placed them (``calibration.markers``; none
      before calibration): a re-calibration's priors, and what marker joints tie to;
    - ``"final"``: what later stages draw, measure and register against: the re-calibrated
      position where the solution has one (``model_solution.markers``), else the calibration's;
    - ``"surveyed"``: the positions ``$.markers`` gives (surveyed markers only);
    - ``"named"``: every marker of ``$.markers`` at the origin (only the names matter: a model's
      handles can be read before calibration);
    - ``"joints"``: what a marker joint may tie to: the calibrated positions, or before
      calibration every named marker (at the origin).
    """
    calibrated = (data.get("calibration") or {}).get("markers")
    if source == "joints":
        source = "calibration" if calibrated is not None else "named"
    if source in ("calibration", "final"):
        records = dict(calibrated or {})
        if source == "final":
            records.update(_recalibrated_markers(data))
        return {n: np.asarray(m["position"], float) for n, m in records.items()}
    if source == "surveyed":
        return {m["name"]: np.asarray(m["position"], float) for m in data.get("markers", []) if "position" in m}
    if source == "named":
        return {m["name"]: np.zeros(3) for m in data.get("markers", [])}
    raise ValueError(f"unknown marker source {source!r}")


def _recalibrated_markers(data: Mapping[str, Any]) -> Mapping[str, Any]:
    return (data.get("model_solution") or {}).get("markers") or {}


def known_points(data: Mapping[str, Any]) -> dict[str, Array]:
    """Positions known after calibration and solving: the final markers (:func:`markers`
    ``"final"``), and the solved model's vertices as ``node:handle`` (``model_solution``)."""
    pts = markers(data, "final")
    for node, entry in (data.get("model_solution") or {}).get("nodes", {}).items():
        for h, v in entry["handles"].items():
            pts[f"{node}:{h}"] = np.asarray(v["value"], float)
    return pts


def marker_sigmas(data: Mapping[str, Any], source: Literal["calibration", "final"] = "calibration"
                  ) -> dict[str, Array]:
    """The markers' 1σ per axis (metres; the largest float where undetermined, 0 where not given),
    as the measurements take them: the calibration's, or with ``"final"`` the re-calibrated 1σ
    where the solution has the marker (as :func:`markers`)."""
    records = dict((data.get("calibration") or {}).get("markers") or {})
    if source == "final":
        records.update(_recalibrated_markers(data))
    return {n: np.nan_to_num(np.asarray([np.inf if s is None else s for s in m.get("sigma", [0, 0, 0])], float),
                             nan=0.0) for n, m in records.items()}


def sightings(photo: Mapping[str, Any]) -> dict[str, Array]:
    """A photo record's marker observations: marker name → (u, v) in pixels."""
    return {n: np.asarray(uv, float) for n, uv in (photo.get("marker_observations") or {}).items()}


def reference_distances(data: Mapping[str, Any]) -> list[ReferenceDistance]:
    """``$.reference_distances``: each with its 1σ (default 2 mm) and role (default ``"scale"``)."""
    return [ReferenceDistance(d["a"], d["b"], float(d["distance"]), float(d.get("sigma", 0.002)),
                              d.get("role", "scale"))
            for d in data.get("reference_distances", [])]


def photo_camera_height(photo: Mapping[str, Any], index: int) -> CameraHeight | None:
    """A photo's ``camera_height`` (metres above the floor, with its 1σ), or None."""
    h = photo.get("camera_height")
    if h is None:
        return None
    return CameraHeight(float(h["value"]), float(h["sigma"]), f"$.photos[{index}].camera_height")


#: 1σ of a known length that gives none, metres: a tape read to the millimetre, as a reference distance's.
DEFAULT_LENGTH_SIGMA_M = 0.002


def known_lengths(data: Mapping[str, Any], photo: str) -> list[KnownLength]:
    """``$.known_lengths`` clicked in ``photo``, each with its JSON path for messages."""
    return [KnownLength(k["axis"], np.asarray(k["ends"], float), float(k["length"]),
                        float(k.get("sigma", DEFAULT_LENGTH_SIGMA_M)), int(k.get("floor_end", 0)),
                        f"$.known_lengths[{i}]")
            for i, k in enumerate(data.get("known_lengths", [])) if k["photo"] == photo]


def floor_markers(data: Mapping[str, Any]) -> set[str]:
    """The markers that lie on the floor (z = 0): those marked ``on_floor``, and the origin marker."""
    out = {m["name"] for m in data.get("markers", []) if m.get("on_floor")}
    if data.get("origin_marker"):
        out.add(data["origin_marker"])
    return out


@dataclass(frozen=True)
class PhotoMarks:
    """What calibrating one photo starts from: its directed vanishing segments by axis, a focal
    length the user gave, and a principal point the user gave (pixels, with its 1σ).

    segments : axis → an (n, 4) array u1, v1, u2, v2 where every segment has two points (as
        before polylines), else a list of (2m,) arrays [u1, v1, ..., um, vm] (polylines with
        middle points); either is what :func:`vebuild.calibration.photo.calibrate_photo` takes.
    """

    segments: dict[str, Array | list[Array]]
    focal: FocalPrior | None
    principal_point: tuple[Array, float] | None


def vanishing_segments(photo: Mapping[str, Any]) -> dict[str, Array | list[Array]]:
    """A photo's ``vanishing_segments`` by axis (axes without segments left out): an (n, 4) array
    where all are two-point segments, else a list of flat polylines (:class:`PhotoMarks`)."""
    out: dict[str, Array | list[Array]] = {}
    for a, rows in (photo.get("vanishing_segments") or {}).items():
        if not rows:
            continue
        polys = [np.asarray(r, float) for r in rows]
        out[a] = np.array(polys).reshape(-1, 4) if all(len(p) == 4 for p in polys) else polys
    return out


def vanishing_segment_sigmas(photo: Mapping[str, Any], click_sigma_px: float) -> dict[str, Array]:
    """Each vanishing segment's 1σ by axis (as :func:`vanishing_segments`): the measured one of a
    detected segment (``vanishing_segment_sigmas``), else the click's."""
    given = photo.get("vanishing_segment_sigmas") or {}
    out: dict[str, Array] = {}
    for a, rows in (photo.get("vanishing_segments") or {}).items():
        if not rows:
            continue
        sig = list(given.get(a) or [])
        sig += [None] * (len(rows) - len(sig))
        out[a] = np.array([click_sigma_px if v is None else float(v) for v in sig[: len(rows)]], float)
    return out


def photo_marks(photo: Mapping[str, Any]) -> PhotoMarks:
    segs = vanishing_segments(photo)
    focal = None
    if "focal_px" in photo:
        focal = FocalPrior(photo["focal_px"]["value"], photo["focal_px"]["sigma"], "user")
    pp = None
    if "principal_point" in photo:
        pp = (np.asarray(photo["principal_point"]["value"], float), float(photo["principal_point"]["sigma"]))
    return PhotoMarks(segs, focal, pp)


# --------------------------------------------------------------------------------------------------
# The model


def located(project: Project, error: ModelError, where: str = "$.model.nodes") -> ProjectError:
    """A :class:`~vebuild.model.scene.ModelError` as a ProjectError of the project's file, at the
    JSON path the error names (``where`` where it names none)."""
    return ProjectError(project.path, error.where or where, error.detail)


def model(project: Project, marker_positions: Mapping[str, Array] | None = None) -> Model:
    """The scene graph of ``$.model.nodes`` with its ``$.model.relations``; a
    :class:`~vebuild.model.scene.ModelError` becomes a
    ProjectError at its JSON path. ``marker_positions``: what marker joints tie to (default: the
    calibrated markers)."""
    if marker_positions is None:
        marker_positions = markers(project.data)
    try:
        return model_nodes(project.data["model"]["nodes"], marker_positions,
                           project.data["model"].get("relations", []))
    except ModelError as e:
        raise located(project, e) from None


def model_nodes(nodes: Sequence[Mapping[str, Any]], marker_positions: Mapping[str, Array],
                relations: Any = None) -> Model:
    """The scene graph of node records being edited (the modelling screen's document in memory)
    and its relations (``$.model.relations``; None: none); a bad one raises the
    :class:`~vebuild.model.scene.ModelError`, whose text names the node
    (``$.model.nodes[2] (node 'box1').joint: ...``) or the relation for the screen to show."""
    return model_from_dict(list(nodes), marker_positions, relations)


def load_model(project: Project, marker_positions: Mapping[str, Array] | None = None
               ) -> tuple[Model, list[Pin], list[EdgeObservation]]:
    """The model and its observations, checked; errors name the file and the JSON path.

    ``marker_positions``: the positions marker joints tie to (default: the calibrated ones).
    """
    data = project.data
    if not data.get("model", {}).get("nodes"):
        raise VebuildError(f"{project.path}: $.model: the project has no model nodes to solve")
    m = model(project, marker_positions)
    pins, edges = pins_of(project, m), edge_observations_of(project, m)
    check_reference_handles(project, m)
    return m, pins, edges


def pins_of(project: Project, decoded: Model) -> list[Pin]:
    """``$.model.pins``, each checked to name a handle its node's primitive has."""
    out = []
    for i, p in enumerate(project.data["model"].get("pins", [])):
        prim = decoded.node(p["node"]).primitive
        if prim is None or p["handle"] not in prim.handle_names():
            have = ", ".join(prim.handle_names()) if prim else "none (a group has no handles)"
            raise ProjectError(project.path, f"$.model.pins[{i}].handle",
                               f"node '{p['node']}' has no handle '{p['handle']}'; its handles are: {have}")
        out.append(Pin(p["photo"], p["node"], p["handle"], np.asarray(p["uv"], float), bool(p.get("fixed", True))))
    return out


def edge_observations_of(project: Project, decoded: Model) -> list[EdgeObservation]:
    """``$.model.edge_observations``, each checked to name an edge its node's primitive has."""
    out = []
    for i, e in enumerate(project.data["model"].get("edge_observations", [])):
        prim = decoded.node(e["node"]).primitive
        names = [n for n, _, _ in prim.edges()] if prim else []
        if e["edge"] not in names:
            raise ProjectError(project.path, f"$.model.edge_observations[{i}].edge",
                               f"node '{e['node']}' has no edge '{e['edge']}'; its edges are: "
                               f"{', '.join(names) or 'none'}")
        out.append(EdgeObservation(e["photo"], e["node"], e["edge"], np.asarray(e["points"], float)))
    return out


def check_reference_handles(project: Project, decoded: Model | None = None) -> None:
    """Every reference distance's ``node:handle`` end names a handle its node's primitive has.

    ``decoded``: the decoded model (default: decoded here, with every marker at the origin, only to
    read the primitives' handles, as before calibration). The load has checked that the node exists.
    """
    refs = [(i, key, d[key]) for i, d in enumerate(project.data.get("reference_distances", []))
            for key in ("a", "b") if ":" in d[key]]
    if not refs:
        return
    if decoded is None:
        decoded = model(project, markers(project.data, "named"))
    for i, key, name in refs:
        node, handle = name.split(":", 1)
        prim = decoded.node(node).primitive
        if prim is None or handle not in prim.handle_names():
            have = ", ".join(prim.handle_names()) if prim else "none (a group has no handles)"
            raise ProjectError(project.path, f"$.reference_distances[{i}].{key}",
                               f"names the handle {name!r}, but node {node!r} has no handle {handle!r}; "
                               f"its handles are: {have}")


# --------------------------------------------------------------------------------------------------
# The solution


@dataclass
class Solution:
    """``model_solution`` decoded: the solved model and the joint covariance in code units.

    names : the covariance's parameters in code units (``node.dof`` radians for angles, metres;
        ``marker:NAME.x`` for re-calibrated markers, last).
    values : their solved values, in that order.
    covariance : their covariance (radians and metres; infinite where undetermined).
    model_index : for each model parameter of ``names``, its index in ``model.vector()``.
    markers, marker_sigma : the final markers' positions and 1σ per axis (:func:`markers` ``"final"``).
    solved_markers : the markers whose covariance ``names`` holds (re-calibrated), in order.
    photos_of : the photos observing each node (and ``marker:NAME``).
    """

    model: Model
    names: list[str]
    values: Array
    covariance: Array
    model_index: list[int]
    markers: dict[str, Array]
    marker_sigma: dict[str, Array]
    solved_markers: list[str]
    photos_of: dict[str, list[str]]
    recalibrated: bool
    variance_factor: float
    calibration_distances: list[dict[str, Any]]


def require_solution(project: Project) -> dict[str, Any]:
    """``model_solution`` with its covariance; a ProjectError if the project has not been solved."""
    sol = project.data.get("model_solution")
    if not sol:
        raise ProjectError(project.path, "$.model_solution", "the project has not been solved yet; "
                           "run `vebuild calibrate` and `vebuild solve` first")
    if not sol.get("covariance"):
        raise ProjectError(project.path, "$.model_solution.covariance", "the solution holds no covariance (written by "
                           "an older vebuild); run `vebuild solve` again")
    return dict(sol)


def solution(project: Project) -> Solution:
    """The solved model (``model.nodes`` holds the solved values) and ``model_solution.covariance``
    with the file's ``NAME_deg`` parameters turned back into radians. Errors name the file and the
    JSON path: not solved, no covariance, a parameter the model no longer has."""
    sol = require_solution(project)
    data, path = project.data, project.path
    rec = sol["covariance"]
    # Marker joints tie to the calibration's markers, as the solve tied them; the markers
    # themselves are where the re-calibration put them (with its 1σ and covariance).
    solved_model = model(project, markers(data))
    placed = markers(data, "final")
    index = {n: i for i, n in enumerate(solved_model.parameter_names())}
    xm = solved_model.vector()
    names: list[str] = []
    values: list[float] = []
    model_index: list[int] = []
    scale: list[float] = []
    solved_markers: list[str] = []
    for k, name in enumerate(rec["parameters"]):
        if name.startswith("marker:"):
            m = name[len("marker:"):].rsplit(".", 1)[0]
            if m not in placed:
                raise ProjectError(path, f"$.model_solution.covariance.parameters[{k}]",
                                   f"marker '{m}' has no calibrated position; run `vebuild solve` again")
            if name.endswith(".x"):
                solved_markers.append(m)
            scale.append(1.0)
            continue
        internal = name[:-4] if name.endswith("_deg") else name
        if internal not in index:
            raise ProjectError(path, f"$.model_solution.covariance.parameters[{k}]",
                               f"'{name}' is not a parameter of the model: the model changed after it was solved; "
                               "run `vebuild solve` again")
        names.append(internal)
        model_index.append(index[internal])
        values.append(xm[index[internal]])
        scale.append(np.radians(1.0) if name.endswith("_deg") else 1.0)
    s = np.asarray(scale)
    cov = np.array([[np.inf if v is None else v for v in row] for row in rec["matrix"]], float)
    cov = cov.reshape(len(s), len(s)) * s[:, None] * s[None, :]
    names += [f"marker:{m}.{c}" for m in solved_markers for c in "xyz"]
    x = np.r_[values, *[placed[m] for m in solved_markers]] if solved_markers else np.asarray(values, float)
    photos: dict[str, set[str]] = {}
    for p in data["model"].get("pins", []) + data["model"].get("edge_observations", []):
        photos.setdefault(p["node"], set()).add(p["photo"])
    for ph in data["photos"]:
        for m in ph.get("marker_observations") or {}:
            photos.setdefault(f"marker:{m}", set()).add(ph["id"])
    cal = data.get("calibration") or {}
    return Solution(solved_model, names, np.asarray(x, float), cov, model_index, placed, marker_sigmas(data, "final"),
                    solved_markers, {k: sorted(v) for k, v in photos.items()}, bool(sol.get("recalibrated")),
                    float(sol.get("variance_factor", 1.0)), list(cal.get("reference_distances") or []))


# --------------------------------------------------------------------------------------------------
# Lighting (FORMAT.md, ``lighting``)


def light_from_record(rec: Mapping[str, Any]) -> Light:
    """A :class:`~vebuild.lighting.Light` from its (validated) record."""
    colour = np.asarray(rec.get("colour", (1.0, 1.0, 1.0)), float) * float(rec.get("intensity", 1.0))
    d = rec.get("direction")
    direction = None if d is None else np.asarray(d, float) / np.linalg.norm(d)
    position = None if rec.get("position") is None else np.asarray(rec["position"], float)
    outer = np.radians(rec.get("outer_cone_deg", DEFAULT_OUTER_CONE_DEG))
    inner = np.radians(rec["inner_cone_deg"]) if "inner_cone_deg" in rec else DEFAULT_INNER_CONE_FRACTION * outer
    return Light(rec["type"], colour, direction, position, float(min(inner, outer)), float(outer),
                 bool(rec.get("shadows", True)), rec.get("name", ""))


def preset_from_record(rec: Mapping[str, Any]) -> Lighting:
    """A :class:`~vebuild.lighting.Lighting` preset from its (validated) record."""
    return Lighting(rec["name"], True, np.asarray(rec.get("ambient", DEFAULT_AMBIENT), float),
                    tuple(light_from_record(r) for r in rec.get("lights", [])), rec.get("description", ""))


def preset_names(project: Project) -> list[str]:
    """The built-in preset and the project's, in order."""
    return [AS_PHOTOGRAPHED] + [p["name"] for p in (project.data.get("lighting") or {}).get("presets", [])]


def find_preset(project: Project, name: str | None) -> Lighting:
    """The preset called ``name`` (None: as photographed); an error listing them if there is none."""
    if name is None or name == AS_PHOTOGRAPHED:
        return AS_PHOTOGRAPHED_LIGHTING
    for rec in (project.data.get("lighting") or {}).get("presets", []):
        if rec["name"] == name:
            return preset_from_record(rec)
    known = ", ".join(repr(n) for n in preset_names(project))
    raise ProjectError(project.path, "$.lighting.presets", f"no lighting preset is called {name!r}; the presets "
                       f"are: {known}")


# --------------------------------------------------------------------------------------------------
# Texture pages (FORMAT.md, "Results: textures")


@dataclass(frozen=True)
class TexturePage:
    """One atlas page as recorded and as read: its bytes hash to the recorded SHA-256."""

    index: int
    path: Path  # the atlas PNG
    relative: str  # as the project records it
    data: bytes
    sha256: str
    size: tuple[int, int]  # width, height in texels
    pixels: NDArray[np.uint8]  # (height, width, 3) sRGB


def texture_pages(project: Project) -> tuple[list[TexturePage], list[Path]]:
    """The project's atlas pages, each read once, checked against its recorded hash and size, and
    decoded; and the pages whose files are missing (not an error: the model is then drawn
    untextured). A page whose bytes changed is an error (ProjectError at its JSON path)."""
    record = project.data.get("textures") or {}
    pages, missing = [], []
    for k, page in enumerate(record.get("pages", [])):
        if not texture_page_path(project, k).is_file():
            missing.append(texture_page_path(project, k))
            continue
        path, raw, digest = read_texture_page(project, k)
        pages.append(TexturePage(k, path, page["atlas"], raw, digest, (int(page["width"]), int(page["height"])),
                                 decode_texture_page(project, k, raw)))
    return pages, missing
