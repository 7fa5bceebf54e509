"""Import an fSpy project as a new vebuild project, and compare fSpy's camera with vebuild's:
``vebuild import FILE.fspy --out FOLDER``.

The fSpy file is read by :mod:`vebuild.project.fspy`. Its marks become vebuild's (docs/fspy.md):

- each vanishing point's two line segments become two **directed** vanishing segments on the
  matching vebuild axis (fSpy ``xPositive``/``xNegative`` → vebuild ``x``, and so on; both frames
  are right-handed, so the axes map one to one). fSpy's segments carry no direction: fSpy takes
  the world axis it is told (``xPositive`` or ``xNegative``) to point *toward* the vanishing point
  in front of the camera, so each segment is directed toward its vanishing point for a positive
  axis and away from it for a negative one (vebuild: from p1 toward p2 in the axis' positive sense);
- quad mode: the second vanishing point's segments join the quad's corners the other way round,
  as fSpy does;
- the third vanishing point (principal point mode ``FromThirdVanishingPoint``) is on the axis
  first × second, its segments directed by the camera's handedness;
- one-vanishing-point mode: fSpy puts the second vanishing point on the line through the first
  along the horizon's direction, orthogonal to it for the given focal length. vebuild's calibration
  needs segments on two axes, so two segments through that point are *derived* (not clicked) on
  the second axis, each as long as the horizon's two control points are apart; the focal length
  (from the lens's millimetres and the sensor size) is given as ``focal_px``. The project records
  that these segments are derived;
- principal point: ``Default`` leaves vebuild's prior at the image centre; ``Manual`` gives the
  point (1σ one click); ``FromThirdVanishingPoint`` lets vebuild estimate it from three vanishing
  points (with its usual prior);
- the origin control point becomes the marker ``fspy_origin`` on the floor, the project's origin;
- the reference distance (fSpy's two handles along an axis from an anchor) becomes the photo's
  ``camera_height``: the height at which vebuild's camera, calibrated from the same marks, puts the
  two handles that distance apart, with its 1σ from the handles' and anchor's clicks and the
  distance's (default 2 mm).

Everything is built in a temporary folder beside ``--out`` and put in place last by the atomic
writer's :func:`~vebuild.project.atomic.place_folder` (one rename, which replaces nothing), so a
failure leaves nothing behind. The original image bytes are written unchanged (their SHA-256 is
checked against the embedded bytes'), the project is calibrated, and the comparison with fSpy's
stored camera (``cameraParameters``, where saved) is returned.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild import __version__
from vebuild.calibration.intrinsics import orthocentre
from vebuild.errors import CalibrationError, ProjectError, VebuildError
from vebuild.project import Project, new_photo_entry, new_project, save_project, sha256_file
from vebuild.project.atomic import MANIFEST, clean_stale, place_folder, remove_tree, temp_path, write_bytes, write_text
from vebuild.project.fspy import (
    AXES,
    MODE_1VP,
    UNITS_M,
    FspyProject,
    Segment,
    axis_vector,
    image_plane_to_pixels,
    read_fspy,
    relative_to_pixels,
)

from .fspy_compare import ComparisonRow, comparison_rows

Array = NDArray[np.float64]

#: The name of the marker made from fSpy's origin control point.
ORIGIN_MARKER = "fspy_origin"
#: 1σ of the reference distance fSpy was given, metres: fSpy keeps none; vebuild's default for a
#: measured distance (FORMAT.md, "Reference distance object").
REFERENCE_SIGMA_M = 0.002
#: A vanishing point's homogeneous w below this share of its norm (in pixels) is at infinity:
#: fSpy cannot solve such a pair of lines either.
PARALLEL_W = 1e-9


@dataclass
class ImportedMarks:
    """The vebuild marks made from one fSpy project (pixels, vebuild's axes)."""

    segments: dict[str, list[list[float]]]
    focal_px: dict[str, float] | None
    principal_point: dict[str, Any] | None
    origin_px: Array
    notes: list[str]
    derived_axis: str | None = None
    vanishing_points: dict[str, Array] = field(default_factory=dict)


@dataclass
class ImportResult:
    project: Path
    photo: Path
    mode: str
    rows: list[ComparisonRow]
    notes: list[str]
    warnings: list[str]
    fspy_camera: bool
    calibrated: bool


# --------------------------------------------------------------------------------------------------
# Marks


def _hom(p: Array) -> Array:
    return np.array([p[0], p[1], 1.0])


def _vanishing_point(segs: list[tuple[Array, Array]], where: str, fp: FspyProject) -> Array:
    """The meeting point (pixels) of two segments' lines; an error where they are parallel."""
    (a, b), (c, d) = segs
    v = np.cross(np.cross(_hom(a), _hom(b)), np.cross(_hom(c), _hom(d)))
    if abs(v[2]) <= PARALLEL_W * np.linalg.norm(v[:2]):
        raise ProjectError(fp.path, where, "the two line segments are parallel in the image: they meet at no "
                           "vanishing point (fSpy cannot solve them either); move one")
    return v[:2] / v[2]


def _pixels(fp: FspyProject, seg: Segment) -> tuple[Array, Array]:
    return relative_to_pixels(seg[0], fp.width, fp.height), relative_to_pixels(seg[1], fp.width, fp.height)


def _directed(p: Array, q: Array, vp: Array, toward: bool) -> list[float]:
    """The segment p–q directed toward the vanishing point ``vp`` (``toward``) or away from it."""
    p_first = np.linalg.norm(q - vp) < np.linalg.norm(p - vp)  # q is nearer the vanishing point
    a, b = (p, q) if p_first == toward else (q, p)
    return [float(a[0]), float(a[1]), float(b[0]), float(b[1])]


def _segment_set(fp: FspyProject, segs: tuple[Segment, Segment], where: str) -> tuple[list[tuple[Array, Array]], Array]:
    px = [_pixels(fp, s) for s in segs]
    for i, (a, b) in enumerate(px):
        if np.linalg.norm(b - a) < 2.0:
            raise ProjectError(fp.path, f"{where}.lineSegments[{i}]", f"the segment's two ends are "
                               f"{np.linalg.norm(b - a):.2f} px apart; expected at least 2 px")
    return px, _vanishing_point(px, f"{where}.lineSegments", fp)


def focal_px_1vp(fp: FspyProject) -> float:
    """fSpy's focal length in pixels for a one-vanishing-point project: its relative focal length
    2F / (the sensor's longer side) times half the image's longer side (fSpy's ``solve1VP``)."""
    assert fp.focal_length_mm is not None and fp.sensor_mm is not None
    sw, sh = fp.sensor_mm
    rel = 2.0 * fp.focal_length_mm / (sw if sw / sh > 1 else sh)
    return rel * max(fp.width, fp.height) / 2.0


def marks_from_fspy(fp: FspyProject, click_sigma_px: float = 1.0, focal_sigma_rel: float = 0.03) -> ImportedMarks:
    """vebuild's marks from an fSpy project's control points (see the module's docstring)."""
    W, H = fp.width, fp.height
    notes: list[str] = []
    base = "$.controlPointsStateBase"
    first, s1 = AXES[fp.first_axis]
    second, s2 = AXES[fp.second_axis]
    segments: dict[str, list[list[float]]] = {}
    vps: dict[str, Array] = {}
    px1, v1 = _segment_set(fp, fp.first_segments, f"{base}.firstVanishingPoint")
    segments[first] = [_directed(a, b, v1, s1 > 0) for a, b in px1]
    vps[first] = v1
    notes.append(f"{first} segments: fSpy's first vanishing point ({fp.first_axis}), directed "
                 f"{'toward' if s1 > 0 else 'away from'} it")
    focal = None
    pp = None
    c = np.array([W / 2.0, H / 2.0])
    if fp.principal_point_mode == "Manual":
        c = relative_to_pixels(fp.principal_point, W, H)
        pp = {"value": [float(c[0]), float(c[1])], "sigma": float(click_sigma_px)}
        notes.append(f"principal point: fSpy's manual principal point, 1σ {click_sigma_px:g} px (one click)")
    elif fp.principal_point_mode == "Default":
        notes.append("principal point: fSpy's default (the image centre): vebuild's prior at the image centre")
    derived = None
    if fp.mode == MODE_1VP:
        assert fp.horizon is not None
        f = focal_px_1vp(fp)
        focal = {"value": float(f), "sigma": float(focal_sigma_rel * f)}
        h0, h1 = _pixels(fp, fp.horizon)
        length = float(np.linalg.norm(h1 - h0))
        if length < 2.0:
            raise ProjectError(fp.path, "$.controlPointsState1VP.horizon", f"the horizon's two control points are "
                               f"{length:.2f} px apart; expected at least 2 px")
        hd = (h1 - h0) / length
        fu = v1 - c
        denom = float(fu @ hd)
        if np.linalg.norm(fu) < 1e-7 * max(W, H) or abs(denom) < 1e-12:
            raise ProjectError(fp.path, "$.controlPointsState1VP.horizon", "the horizon runs at right angles to the "
                               "line from the principal point to the first vanishing point (or that vanishing point "
                               "is the principal point): fSpy finds no second vanishing point")
        k = -(fu @ fu + f * f) / denom
        v2 = v1 + k * hd
        segments[second] = _derived_segments(v2, W, H, length, s2 > 0)
        vps[second] = v2
        derived = second
        sensor = f"{fp.sensor_mm[0]:g} × {fp.sensor_mm[1]:g} mm" if fp.sensor_mm else "?"
        notes.append(f"{second} segments: DERIVED, not clicked: two segments through fSpy's second vanishing point "
                     f"({fp.second_axis}), which fSpy puts on the line through the first along the horizon, for the "
                     f"focal length {fp.focal_length_mm:g} mm on {fp.sensor_source} ({sensor})")
        notes.append(f"focal length: {f:.2f} px from fSpy's {fp.focal_length_mm:g} mm, given as focal_px with 1σ "
                     f"{100 * focal_sigma_rel:g} % (a lens's nominal focal length)")
    else:
        assert fp.second_segments is not None
        where = f"{base}.firstVanishingPoint" if fp.quad_mode else "$.controlPointsState2VP.secondVanishingPoint"
        px2, v2 = _segment_set(fp, fp.second_segments, where)
        segments[second] = [_directed(a, b, v2, s2 > 0) for a, b in px2]
        vps[second] = v2
        how = "the quad's corners paired the other way (quad mode)" if fp.quad_mode else "fSpy's second vanishing point"
        notes.append(f"{second} segments: {how} ({fp.second_axis}), directed {'toward' if s2 > 0 else 'away from'} it")
        if fp.third_segments is not None:
            third, s3 = AXES[fp.third_axis]
            px3, v3 = _segment_set(fp, fp.third_segments, "$.controlPointsState2VP.thirdVanishingPoint")
            try:
                c3 = orthocentre(v1, v2, v3)
            except np.linalg.LinAlgError:
                raise ProjectError(fp.path, "$.controlPointsState2VP.thirdVanishingPoint", "the three vanishing points "
                                   "lie on one line: they give no principal point") from None
            # The camera directions of the first and second axes point at their vanishing points
            # (u − cx, v − cy, f); the third axis is their cross product, whose depth sign is
            # independent of f: toward its vanishing point where positive.
            z3 = float((v1[0] - c3[0]) * (v2[1] - c3[1]) - (v1[1] - c3[1]) * (v2[0] - c3[0]))
            toward = s3 * z3 > 0
            segments[third] = [_directed(a, b, v3, toward) for a, b in px3]
            vps[third] = v3
            notes.append(f"{third} segments: fSpy's third vanishing point ({fp.third_axis} = first × second); "
                         "principal point estimated by vebuild from the three vanishing points")
    origin = relative_to_pixels(fp.origin, W, H)
    return ImportedMarks(segments, focal, pp, origin, notes, derived, vps)


def _derived_segments(vp: Array, W: int, H: int, length: float, toward: bool) -> list[list[float]]:
    """Two segments whose lines meet at ``vp``, through points a quarter of the image above and
    below its centre, each ``length`` long (no longer than half their distance to ``vp``)."""
    out = []
    for dy in (-0.25, 0.25):
        m = np.array([W / 2.0, H / 2.0 + dy * H])
        d = vp - m
        dist = float(np.linalg.norm(d))
        if dist < 4.0:  # the vanishing point lies on this anchor: move it sideways
            m = m + np.array([0.25 * W, 0.0])
            d = vp - m
            dist = float(np.linalg.norm(d))
        half = 0.5 * min(length, dist)
        u = d / dist
        p, q = m - half * u, m + half * u
        out.append(_directed(p, q, vp, toward))
    return out


# --------------------------------------------------------------------------------------------------
# The reference distance → the camera's height


def _ray(K: Array, R: Array, uv: Array) -> Array:
    return np.asarray(R.T @ np.linalg.solve(K, _hom(uv)), float)


def handle_pixels(fp: FspyProject, vp_px: Array) -> tuple[Array, Array, Array]:
    """fSpy's reference distance anchor and its two handles, pixels: the handles lie on the line
    from the anchor toward the reference axis' vanishing point, at the stored offsets measured in
    relative coordinates (fSpy's ``referenceDistanceHandlesRelativePositions``)."""
    W, H = fp.width, fp.height
    anchor = np.array(fp.reference_anchor, float)
    vp_rel = vp_px / np.array([W, H], float)
    d = vp_rel - anchor
    d = d / np.linalg.norm(d)
    hs = [anchor + o * d for o in fp.reference_offsets]
    scale = np.array([W, H], float)
    return anchor * scale, hs[0] * scale, hs[1] * scale


def handle_distance(K: Array, R: Array, axis: Array, origin: Array, anchor: Array, h0: Array, h1: Array) -> float:
    """The distance between the two handles in space for a camera at height 1 above the floor whose
    origin ray meets the floor at the world origin: the anchor lies in the plane through the origin
    normal to the reference axis; each handle is the point of the line through the anchor along the
    axis nearest its ray (fSpy's ``referenceDistanceHandlesWorldPositions``)."""
    ro = _ray(K, R, origin)
    if ro[2] >= 0:
        raise ValueError("the origin is not below the horizon")
    C = ro / ro[2]  # C + s·ro = 0 at s = −1/ro_z: C_z = 1
    ra = _ray(K, R, anchor)
    den = float(ra @ axis)
    if abs(den) < 1e-12:
        raise ValueError("the anchor's ray runs in the reference plane")
    Xa = C + (-(C @ axis) / den) * ra
    ts = []
    for h in (h0, h1):
        r = _ray(K, R, h)
        # Closest points of C + s r and Xa + t axis.
        A = np.array([[r @ r, -(r @ axis)], [r @ axis, -(axis @ axis)]])
        b = np.array([(Xa - C) @ r, (Xa - C) @ axis])
        _, t = np.linalg.solve(A, b)
        ts.append(float(t))
    return abs(ts[1] - ts[0])


def camera_height_from_reference(fp: FspyProject, K: Array, R: Array, origin: Array, vp_px: Array,
                                 click_sigma_px: float) -> tuple[float, float, dict[str, Any]]:
    """The camera's height (metres) and its 1σ at which the handles are the reference distance apart."""
    assert fp.reference_axis is not None
    unit = UNITS_M[fp.reference_unit]
    assert unit is not None
    L = fp.reference_distance * unit
    axis = axis_vector(fp.reference_axis)
    anchor, h0, h1 = handle_pixels(fp, vp_px)
    x0 = np.concatenate([origin, anchor, h0, h1])

    def d_of(x: Array) -> float:
        return handle_distance(K, R, axis, x[0:2], x[2:4], x[4:6], x[6:8])

    d = d_of(x0)
    grad = np.zeros(8)
    for i in range(8):
        e = np.zeros(8)
        e[i] = 0.05
        grad[i] = (d_of(x0 + e) - d_of(x0 - e)) / 0.1
    sd = float(np.linalg.norm(grad) * click_sigma_px)
    h = L / d
    sigma = h * math.hypot(REFERENCE_SIGMA_M / L, sd / d)
    info = {"anchor_px": anchor.tolist(), "handles_px": [h0.tolist(), h1.tolist()], "distance_m": L}
    return h, sigma, info


# --------------------------------------------------------------------------------------------------
# The import


def check_out_folder(out: Path) -> None:
    """Refuse (VebuildError) an output folder that exists and is not empty, a link or a file."""
    if out.is_symlink():
        raise VebuildError(f"{out}: is a symbolic link; choose a new folder for the imported project")
    if out.exists():
        if os.path.realpath(out) == os.path.realpath(os.getcwd()):
            raise VebuildError(f"{out}: is the folder you are working in; vebuild puts the imported project in place "
                               "as a new folder: choose another --out")
        if not out.is_dir():
            raise VebuildError(f"{out}: is a file; expected a new (or empty) folder for the imported project")
        if any(out.iterdir()):
            shown = ", ".join(sorted(p.name for p in out.iterdir())[:3])
            raise VebuildError(f"{out}: is not empty (it holds {shown}); vebuild imports into a new or empty folder "
                               "only: choose another --out")
    if not out.parent.is_dir():
        raise VebuildError(f"{out.parent}: no such folder (the parent of --out)")


def _safe_name(stem: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", stem).strip("._") or "photo"


def import_fspy(fspy_file: str | os.PathLike[str], out: str | os.PathLike[str], *, click_sigma_px: float = 1.0,
                name: str | None = None) -> ImportResult:
    """Read ``fspy_file``, write a new project folder ``out`` (photo + ``NAME.vebuild.json``),
    calibrate it and compare with fSpy's stored camera.

    Raises
    ------
    ProjectError / VebuildError : the fSpy file is bad (naming the field), or ``out`` is not a new
        or empty folder. Nothing is written then.
    """
    src = Path(fspy_file)
    out = Path(out)
    if not (isinstance(click_sigma_px, (int, float)) and 0.001 <= click_sigma_px <= 1000):
        raise VebuildError(f"--click-sigma: expected a 1σ of 0.001 to 1000 pixels, found {click_sigma_px!r}")
    check_out_folder(out)
    fp = read_fspy(src)
    stem = _safe_name(src.stem)
    marks = marks_from_fspy(fp, click_sigma_px)
    clean_stale(out.parent)  # a staging folder left by an import that was killed
    staging = temp_path(out)
    try:
        staging.mkdir()
    except OSError as e:
        raise VebuildError(f"{out.parent}: cannot make the folder to build the imported project in "
                           f"({e.strerror or e}); nothing was written") from None
    try:
        # Marked as vebuild's while it is built, so that clean_stale removes it if this process dies.
        write_text(staging / MANIFEST, json.dumps({"software": f"vebuild {__version__}", "kind": "import",
                                                   "files": {}}) + "\n")
        result = _build(fp, src, staging, out, stem, marks, click_sigma_px, name)
        (staging / MANIFEST).unlink()
        check_out_folder(out)  # nothing appeared there meanwhile
        place_folder(staging, out)  # refused, replacing nothing, if anything appears there even now
    except OSError as e:
        remove_tree(staging)
        raise VebuildError(f"{out}: cannot write the imported project ({e.strerror or e}); nothing was "
                           "written") from None
    except BaseException:
        remove_tree(staging)
        raise
    result.project = out / result.project.name
    result.photo = out / result.photo.name
    return result


def _build(fp: FspyProject, src: Path, folder: Path, out: Path, stem: str, marks: ImportedMarks,
           click_sigma_px: float, name: str | None) -> ImportResult:
    from .calibrate import calibrate_photos, calibrate_project

    photo_path = folder / f"{stem}{fp.image_ending}"
    write_bytes(photo_path, fp.image)
    entry = new_photo_entry(folder, photo_path, stem)
    if entry["sha256"] != fp.image_sha256:  # pragma: no cover - the bytes were written as read
        raise VebuildError(f"{photo_path}: the photo written does not hash to the embedded image's SHA-256")
    if (entry["width"], entry["height"]) != (fp.width, fp.height):  # pragma: no cover - same decoder
        raise VebuildError(f"{photo_path}: size {entry['width']}×{entry['height']} differs from the embedded image's")
    warnings: list[str] = []
    cam = fp.camera
    if cam is not None and (round(cam.image_width), round(cam.image_height)) != (fp.width, fp.height):
        raise ProjectError(fp.path, "$.cameraParameters.imageWidth", f"fSpy solved an image of "
                           f"{cam.image_width:g}×{cam.image_height:g} pixels, but the embedded image is "
                           f"{fp.width}×{fp.height} as displayed (turned by its EXIF orientation): the marks would "
                           "not fall where they were placed")
    entry["vanishing_segments"] = marks.segments
    entry["marker_observations"] = {ORIGIN_MARKER: [float(marks.origin_px[0]), float(marks.origin_px[1])]}
    if marks.focal_px is not None:
        entry["focal_px"] = marks.focal_px
    if marks.principal_point is not None:
        entry["principal_point"] = marks.principal_point
    notes = list(marks.notes)
    notes.append(f"origin: fSpy's origin control point, the marker {ORIGIN_MARKER} on the floor (z = 0)")
    data = new_project(name or src.stem)
    data["settings"]["click_sigma_px"] = float(click_sigma_px)
    data["markers"] = [{"name": ORIGIN_MARKER, "description": "fSpy's origin control point (the world origin)",
                        "on_floor": True}]
    data["origin_marker"] = ORIGIN_MARKER
    data["photos"] = [entry]
    entry["imported_from"] = {"software": "fSpy", "file": src.name, "sha256": sha256_file(src), "notes": notes}
    project_path = folder / f"{stem}.vebuild.json"
    project = Project(project_path, data)
    guide = (fp.state.get("globalSettings") or {}).get("overlay3DGuide")
    if guide in ("YZGridFloor", "ZXGridFloor"):
        warnings.append(f"fSpy showed the {guide[:2]} plane as the floor; vebuild's floor is z = 0 (+Z up) and takes "
                        "fSpy's axes as they are: choose the axes in fSpy so that z is up")
    calibrated = True
    scaled = False
    try:
        first_pass = calibrate_photos(project)[stem]
        if fp.reference_axis is not None:
            if UNITS_M[fp.reference_unit] is None:
                warnings.append("fSpy's reference distance has no unit ('No unit'): lengths stay relative")
            else:
                letter = AXES[fp.reference_axis][0]
                if cam is not None:
                    i = [AXES[a][0] for a in cam.vanishing_point_axes].index(letter)
                    vp = image_plane_to_pixels(cam.vanishing_points[i], fp.width, fp.height)
                else:
                    v = first_pass.K @ first_pass.R @ axis_vector(fp.reference_axis)
                    vp = v[:2] / v[2]
                try:
                    h, sh, info = camera_height_from_reference(fp, first_pass.K, first_pass.R, marks.origin_px, vp,
                                                               click_sigma_px)
                except (ValueError, np.linalg.LinAlgError) as e:
                    warnings.append(f"fSpy's reference distance could not be used ({e}); lengths stay relative")
                else:
                    if not 1e-3 <= h <= 1e4:
                        raise ProjectError(fp.path, "$.calibrationSettingsBase.referenceDistance",
                                           f"the reference distance puts the camera {h:.4g} m above the floor; "
                                           "expected 1 mm to 10 km: check the distance and its unit")
                    entry["camera_height"] = {"value": float(h), "sigma": float(max(sh, 1e-6))}
                    notes.append(f"camera_height: from fSpy's reference distance {fp.reference_distance:g} "
                                 f"{fp.reference_unit} ({info['distance_m']:.4g} m, "
                                 f"1σ {REFERENCE_SIGMA_M * 1000:g} mm) "
                                 f"along {fp.reference_axis}, anchor at {_px(info['anchor_px'])}, handles at "
                                 f"{_px(info['handles_px'][0])} and {_px(info['handles_px'][1])}: the height at which "
                                 "vebuild's calibrated camera puts the handles that far apart")
                    scaled = True
        else:
            notes.append("no reference distance in fSpy: lengths are relative (camera height 1)")
        calibrate_project(project)
    except CalibrationError as e:
        calibrated = False
        project.data.pop("calibration", None)
        said = str(e).replace(str(folder), str(out))  # name the folder the project will be in
        if str(out) not in said:
            said = f"{out / project_path.name}: {said}"
        warnings.append(f"vebuild could not calibrate the photo: {said}. The marks are imported as fSpy had them; "
                        "vebuild's world has +Z up and the origin on the floor: check fSpy's axes (a vanishing "
                        "point's axis points toward it, so a camera looking down sees zNegative's)")
    save_project(project)
    rows = comparison_rows(fp, project.data, stem, scaled) if calibrated else []
    return ImportResult(project_path, photo_path, fp.mode, rows, notes, warnings, cam is not None, calibrated)


def _px(p: Any) -> str:
    return f"({p[0]:.1f}, {p[1]:.1f}) px"


__all__ = ["ImportResult", "ImportedMarks", "camera_height_from_reference", "import_fspy", "marks_from_fspy"]
