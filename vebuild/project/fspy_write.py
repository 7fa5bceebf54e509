"""A calibrated photo as an fSpy project (``.fspy``): what fSpy (github.com/stuffmatic/fSpy) opens
and what its Blender add-on (github.com/stuffmatic/fSpy-Blender) imports, so that a user of the
fSpy → Blender workflow can take vebuild's camera there (docs/export.md).

The file is fSpy's (``project_file_format.md``; read by :mod:`vebuild.project.fspy`): ``fspy``,
uint32 version 1, uint32 state size, uint32 image size (little-endian), the state as JSON, the
image's bytes (:mod:`vebuild.project.handoff_image`: the photo's own file where another program
shows it as vebuild does).

The Blender add-on (``fspy_blender/fspy.py``, ``addon.py``) reads only the header, the image, the
state's ``calibrationSettingsBase.referenceDistanceUnit`` and its ``cameraParameters``:
``principalPoint`` {x, y}, ``horizontalFieldOfView``, ``cameraTransform.rows``, ``imageWidth``,
``imageHeight``. It sets the camera's angle to the field of view (Blender fits it to the longer
side), its world matrix to ``cameraTransform`` and its shift from the principal point. fSpy's
conventions, which vebuild's are turned into here:

- **image plane** coordinates (``principalPoint``, ``vanishingPoints``): origin at the image's
  centre, x right, y *up*, one unit = half the image's *longer* side;
- **relative** coordinates (control points): x / width, y / height from the top-left corner, y down;
- ``viewTransform``: world → camera, the camera OpenGL's (x right, y up, looking along −z), so its
  rotation is diag(1, −1, −1) · R; its translation in the reference distance's unit (metres here,
  vebuild's lengths; relative units where the photo has no scale, and the unit "No unit");
  ``cameraTransform`` its inverse; world axes as vebuild's (right-handed, +Z up: Blender's too);
- ``horizontalFieldOfView`` = 2 atan(1 / relativeFocalLength) across the longer side,
  ``verticalFieldOfView`` = 2 atan((height / width) / relativeFocalLength) as fSpy computes it,
  ``relativeFocalLength`` = f / (half the longer side).

fSpy itself re-solves a project from its control points when it opens it, so the control points
written are those that give this same camera: two segments through each of the two vanishing
points best seen in the photo (``TwoVanishingPoints``), the principal point placed by hand
(``Manual``) where vebuild has it, the origin where the world's origin projects, and the
reference distance (metric photos) along the axis whose unit length the photo shows longest,
from the origin, 1 m long (shorter where the origin lies far off the photo). fSpy and Blender have
no lens distortion: a photo with k1 ≠ 0 is handed on as its pinhole camera, with a warning of how
far the lens moves its corners. Where the world's origin lies behind the camera, or below it (the
camera then lies in every reference plane through the origin, so fSpy's reference distance cannot
scale it), the control points put fSpy's origin on a floor point in view, which the command names:
fSpy shows the same camera moved by it; the stored camera (what Blender reads) stays exact.
"""

from __future__ import annotations

import json
import math
import struct
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, distortion_displacement_px

from .file import Project
from .fspy import MAGIC, VERSION

Array = NDArray[np.float64]

#: fSpy's camera (OpenGL) from vebuild's (computer vision): y and z flipped.
GL_FROM_CV = np.diag([1.0, -1.0, -1.0])
#: The reference distance written for a metric photo: the handles this far apart (metres), the
#: longest of these whose second handle lies within MAX_HANDLE_OFFSET photo sides of the first.
REFERENCE_LENGTHS = (1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01)
MAX_HANDLE_OFFSET = 2.0
#: A reference axis needs the camera this far (a share of its distance from the origin) off the
#: plane through the origin normal to it, and its two handles this many pixels apart.
MIN_OFF_PLANE = 0.05
MIN_HANDLE_PX = 5.0
#: fSpy's defaults for what vebuild does not use (src/gui/defaults/*.ts).
CAMERA_DATA = {"presetId": None, "presetData": None, "customSensorWidth": 36, "customSensorHeight": 24}
RESULT_DISPLAY = {"orientationFormat": "AxisAngleDegrees", "principalPointFormat": "Absolute",
                  "fieldOfViewFormat": "Degrees", "displayAbsoluteFocalLength": False}
#: A direction whose depth in the camera (|d_z| of a unit vector) is below this has its vanishing
#: point too far off the photo for fSpy to use it.
MIN_VP_DEPTH = 1e-3


def _point(p: Array) -> dict[str, float]:
    return {"x": float(p[0]), "y": float(p[1])}


def image_plane(uv: Array, W: int, H: int) -> Array:
    """vebuild pixels → fSpy's image plane coordinates (inverse of ``image_plane_to_pixels``)."""
    s = max(W, H) / 2.0
    return np.array([(uv[0] - W / 2.0) / s, (H / 2.0 - uv[1]) / s])


def relative(uv: Array, W: int, H: int) -> dict[str, float]:
    return {"x": float(uv[0] / W), "y": float(uv[1] / H)}


def _axis_name(letter: str, sign: float) -> str:
    return f"{letter}{'Positive' if sign > 0 else 'Negative'}"


def _segments_through(V: Array, W: int, H: int) -> list[list[dict[str, float]]]:
    """Two segments (relative coordinates) whose lines meet at the homogeneous image point ``V``
    (pixels; w = 0 for a point at infinity), through two points a fifth of the image apart."""
    centre = np.array([W / 2.0, H / 2.0])
    toward = V[:2] - centre * V[2]
    n = np.array([-toward[1], toward[0]])
    n = n / np.linalg.norm(n) if np.linalg.norm(n) > 1e-12 else np.array([0.0, 1.0])
    short = min(W, H)
    out = []
    for side in (-1.0, 1.0):
        m = centre + side * 0.2 * short * n
        d = V[:2] - m * V[2]
        if V[2] < 0:
            d = -d
        if np.linalg.norm(d) < 1e-9:  # the vanishing point is this anchor: any line through it
            d = n.copy()
        d = d / np.linalg.norm(d)
        a, b = m - 0.125 * short * d, m + 0.125 * short * d
        out.append([relative(a, W, H), relative(b, W, H)])
    return out


def fspy_state(cam: ImageCamera, relative_units: bool) -> tuple[dict[str, Any], list[str], list[str]]:
    """The fSpy state of ``cam`` (module docstring), with notes and warnings in words."""
    W, H = int(cam.width), int(cam.height)
    K, R, C = np.asarray(cam.K, float), np.asarray(cam.R, float), np.asarray(cam.C, float)
    f = float(K[0, 0])
    s = max(W, H) / 2.0
    notes: list[str] = []
    warnings: list[str] = []
    # Each world axis' direction in the camera, signed so that it points in front (toward its vanishing point).
    dirs = {a: R[:, i] for i, a in enumerate("xyz")}
    depth = {a: abs(float(d[2])) for a, d in dirs.items()}
    pairs = [("x", "y"), ("x", "z"), ("y", "z")]
    first, second = max(pairs, key=lambda p: min(depth[p[0]], depth[p[1]]))
    if min(depth[first], depth[second]) < MIN_VP_DEPTH:
        warnings.append("the photo shows no two axes' vanishing points well (it looks straight along one axis): "
                        "fSpy may not re-solve its control points; the Blender add-on reads the camera as written")
    sign = {a: 1.0 if dirs[a][2] >= 0 else -1.0 for a in "xyz"}
    axes = [_axis_name(first, sign[first]), _axis_name(second, sign[second])]
    e1 = sign[first] * np.eye(3)["xyz".index(first)]
    e2 = sign[second] * np.eye(3)["xyz".index(second)]
    e3 = np.cross(e1, e2)
    third_letter = "xyz"[int(np.argmax(np.abs(e3)))]
    axes.append(_axis_name(third_letter, float(e3.max() + e3.min())))

    def vp_h(e: Array) -> Array:
        v = K @ R @ e
        return np.asarray(v, float)

    vph = [vp_h(e) for e in (e1, e2, e3)]

    def vp_plane(v: Array) -> Array:
        w = v[2] if abs(v[2]) > 1e-12 else math.copysign(1e-12, v[2] or 1.0)
        return image_plane(v[:2] / w, W, H)

    Rgl = GL_FROM_CV @ R
    view = np.eye(4)
    view[:3, :3] = Rgl
    view[:3, 3] = -Rgl @ C
    pp = K[:2, 2]
    f_rel = f / s
    camera = {
        "principalPoint": _point(image_plane(pp, W, H)),
        "viewTransform": {"rows": view.tolist()},
        "cameraTransform": {"rows": np.linalg.inv(view).tolist()},
        "horizontalFieldOfView": 2.0 * math.atan(1.0 / f_rel),
        "verticalFieldOfView": 2.0 * math.atan((H / W) / f_rel),
        "vanishingPoints": [_point(vp_plane(v)) for v in vph],
        "vanishingPointAxes": axes,
        "relativeFocalLength": f_rel,
        "imageWidth": W,
        "imageHeight": H,
    }
    # Control points that make fSpy's solver give this camera: its origin where the world's shows.
    ref = _reference(K, R, C, np.zeros(3), vph, axes, W, H, relative_units)
    if ref is None:  # fSpy cannot anchor this world's origin: a floor point in view stands for it
        stand_in = _floor_in_view(K, R, C, W, H)
        ref = None if stand_in is None else _reference(K, R, C, stand_in, vph, axes, W, H, relative_units)
        if ref is None or stand_in is None:
            warnings.append("the world's origin cannot be placed in fSpy (it lies behind the camera, or below it where "
                            "fSpy's reference distance cannot give the scale) and no floor shows in the photo to "
                            "stand for it: fSpy, re-solving the control points when it opens the file, places the "
                            "camera elsewhere; the Blender add-on reads the camera as written, in vebuild's world")
            ref = (pp, None, [0.0, REFERENCE_LENGTHS[0]], REFERENCE_LENGTHS[0])
        else:
            x, y = float(stand_in[0]), float(stand_in[1])
            warnings.append(f"the world's origin (the floor below the camera, or behind it) cannot anchor fSpy's "
                            f"reference distance: the file's origin control point is the floor point ({x:.3f}, "
                            f"{y:.3f}, 0) in view, so fSpy, re-solving the control points when it opens the file, "
                            f"shows the same camera moved by ({-x:.3f}, {-y:.3f}, 0); the Blender add-on reads the "
                            "camera as written, in vebuild's world")
    origin_px, ref_axis, offsets, reference = ref
    if ref_axis is not None:
        notes.append(f"reference distance: {reference:g} m along +{ref_axis} from fSpy's origin")
    state: dict[str, Any] = {
        "globalSettings": {"calibrationMode": "TwoVanishingPoints", "overlay3DGuide": "XYGridFloor",
                           "imageOpacity": 1.0},
        "calibrationSettingsBase": {
            "referenceDistanceUnit": "No unit" if relative_units else "Meters",
            "referenceDistance": reference,
            "referenceDistanceAxis": None if ref_axis is None else f"{ref_axis}Positive",
            "cameraData": dict(CAMERA_DATA),
            "firstVanishingPointAxis": axes[0],
            "secondVanishingPointAxis": axes[1],
        },
        "calibrationSettings1VP": {"principalPointMode": "Default", "absoluteFocalLength": 24},
        "calibrationSettings2VP": {"principalPointMode": "Manual", "quadModeEnabled": False},
        "controlPointsStateBase": {
            "principalPoint": relative(pp, W, H),
            "origin": relative(origin_px, W, H),
            "referenceDistanceAnchor": relative(origin_px, W, H),
            "firstVanishingPoint": {"lineSegments": _segments_through(vph[0], W, H)},
            "referenceDistanceHandleOffsets": offsets,
        },
        "controlPointsState1VP": {"horizon": [{"x": 0.2, "y": 0.5}, {"x": 0.8, "y": 0.5}]},
        "controlPointsState2VP": {"secondVanishingPoint": {"lineSegments": _segments_through(vph[1], W, H)},
                                  "thirdVanishingPoint": {"lineSegments": _segments_through(vph[2], W, H)}},
        "cameraParameters": camera,
        "resultDisplaySettings": dict(RESULT_DISPLAY),
    }
    notes.insert(0, f"vanishing points: {axes[0]} and {axes[1]} (two segments through each), principal point "
                    f"placed by hand at ({pp[0]:.2f}, {pp[1]:.2f}) px")
    if relative_units:
        notes.append("lengths are relative (the camera height is 1): fSpy's unit is 'No unit'")
    if not cam.lens.is_pinhole:
        second = f", k2 {cam.lens.k2:+.4g}" if cam.lens.k2 != 0.0 else ""
        warnings.append(f"the photo's lens distortion (k1 {cam.lens.k1:+.4g}{second}, moving its corners by "
                        f"{distortion_displacement_px(K, W, H, cam.lens):.1f} px) has no place in fSpy or Blender: the "
                        "camera written is its pinhole part, so lines drift from the photo toward its corners by up "
                        "to that much")
    return state, notes, warnings


def _floor_in_view(K: Array, R: Array, C: Array, W: int, H: int) -> Array | None:
    """A floor point (z = 0) the photo shows, below its principal point three quarters of the way
    down (or at its foot), or None where the camera sees no floor there."""
    if C[2] <= 0:
        return None
    for v in (0.75 * H, 0.95 * H):
        d = R.T @ np.linalg.solve(K, np.array([K[0, 2], v, 1.0]))
        if d[2] < -1e-3:
            return np.asarray(C + d * (-C[2] / d[2]), float)
    return None


def _reference(K: Array, R: Array, C: Array, at: Array, vph: list[Array], axes: list[str], W: int, H: int,
               relative_units: bool) -> tuple[Array, str | None, list[float], float] | None:
    """fSpy's origin control point (pixels) at the world point ``at``, and its reference distance from
    there: the axis, the handles' offsets and the length; None where it cannot serve (behind the
    camera, or, for a photo in metres, no axis whose reference plane through it the camera is off)."""
    o = K @ R @ (at - C)
    rel = C - at
    if not o[2] > 1e-6 * max(1.0, float(np.linalg.norm(rel))):
        return None
    origin_px = o[:2] / o[2]
    if relative_units:
        return origin_px, None, [0.0, REFERENCE_LENGTHS[0]], REFERENCE_LENGTHS[0]
    best, ref_axis = 0.0, None
    for i, a in enumerate("xyz"):
        h = K @ R @ (at + REFERENCE_LENGTHS[0] * np.eye(3)[i] - C)
        if h[2] <= 1e-6 or abs(rel[i]) < MIN_OFF_PLANE * np.linalg.norm(rel):
            continue  # behind the camera, or the camera in the plane the anchor's ray must cross
        span = float(np.linalg.norm(h[:2] / h[2] - origin_px))
        if span > max(best, MIN_HANDLE_PX):
            best, ref_axis = span, a
    if ref_axis is None:
        return None
    v = vph[next(i for i, n in enumerate(axes) if n[0] == ref_axis)]
    w = v[2] if abs(v[2]) > 1e-12 else math.copysign(1e-12, v[2] or 1.0)
    vp_rel = np.array([v[0] / w / W, v[1] / w / H])
    anchor = np.array([origin_px[0] / W, origin_px[1] / H])
    d = (vp_rel - anchor) / np.linalg.norm(vp_rel - anchor)
    offsets = [0.0, 0.0]
    for length in REFERENCE_LENGTHS:  # the longest whose handle lies within fSpy's reach of the anchor
        h = K @ R @ (at + length * np.eye(3)["xyz".index(ref_axis)] - C)
        h_rel = np.array([h[0] / h[2] / W, h[1] / h[2] / H])
        offsets = [0.0, float((h_rel - anchor) @ d)]
        if h[2] > 0 and abs(offsets[1]) <= MAX_HANDLE_OFFSET:
            break
    return origin_px, ref_axis, offsets, length


def fspy_bytes(state: dict[str, Any], image: bytes) -> bytes:
    """The file as fSpy's ``ProjectFile.save`` writes it: header, ``JSON.stringify(state)``, image."""
    raw = json.dumps(state, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
    return MAGIC + struct.pack("<III", VERSION, len(raw), len(image)) + raw + image


def fspy_project(project: Project, photo: str, cam: ImageCamera) -> tuple[bytes, list[str], list[str]]:
    """The ``.fspy`` file of ``photo`` (module docstring), with what it holds and warnings, in words."""
    from .handoff_image import handoff_image
    from .units import length_unit

    image = handoff_image(project, photo)
    if image.size != (int(cam.width), int(cam.height)):
        raise ValueError("the photo's image and its camera differ in size")
    relative_units = length_unit(project.data).relative
    state, notes, warnings = fspy_state(cam, relative_units)
    c = state["cameraParameters"]
    details = [f"camera: horizontal field of view {math.degrees(c['horizontalFieldOfView']):.3f}° (across the "
               f"longer side), principal point ({c['principalPoint']['x']:+.5f}, {c['principalPoint']['y']:+.5f}) "
               f"in fSpy's image plane, units "
               f"{state['calibrationSettingsBase']['referenceDistanceUnit']}", *notes, f"photo: {image.note}",
               "open it in Blender with the fSpy add-on (File > Import > fSpy), or in fSpy"]
    return fspy_bytes(state, image.data), details, warnings
