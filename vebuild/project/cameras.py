"""The cameras of the project document (layer 3; re-exported by :mod:`vebuild.project.decode`,
the one decoder of the document, whose errors these share): the calibration stage's
(:func:`cameras_from_calibration`, a re-calibration's priors), the final ones later stages use
(:func:`cameras`: re-calibrated where the solution has them, as
:func:`~vebuild.project.camera_records.camera_records` says), one photo's
(:func:`photo_camera`) and the named evidence views' (:func:`view_camera`, :func:`find_view`).
Each is checked as it is decoded: K a pinhole matrix, R a rotation, k1 within the division
model's bounds; errors name the file and the JSON path."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, Lens, fov_to_focal, intrinsic_matrix, look_rotation
from vebuild.errors import ProjectError, VebuildError

from .camera_records import recalibrated_cameras
from .file import Project
from .json_paths import json_path

Array = NDArray[np.float64]

#: How far a calibrated R may be from a rotation (|RᵀR − I|, |det R − 1|): rounding in the file's
#: 17 significant digits is far below; anything more is not a rotation.
ROTATION_TOLERANCE = 1e-6
#: Horizontal field of view of a view that gives neither ``fov_deg`` nor ``focal_length_mm``.
DEFAULT_FOV_DEG = 60.0
#: Width of the 35 mm film frame, for 35 mm-equivalent focal lengths.
FRAME_35MM_WIDTH_MM = 36.0




def cameras_from_calibration(project: Project) -> dict[str, ImageCamera]:
    """The cameras of the calibration stage (``calibration.cameras``: vanishing points, placement,
    registration) by photo id: the priors of a re-calibrating solve. Each is checked: K a pinhole
    matrix with a positive focal length, R a rotation; errors name the file and the JSON path. Each
    carries its photo's size and its calibration covariance (9×9 over f, cx, cy, ω, C; infinite
    where undetermined). Later stages draw with :func:`cameras`."""
    cal = project.data.get("calibration")
    if not cal or not cal.get("cameras"):
        raise VebuildError(f"{project.path}: the project has no calibrated cameras; run `vebuild calibrate` first")
    check_calibration_stage(project)
    return _cameras_from_records(project, cal["cameras"], "calibration")


def check_calibration_stage(project: Project) -> None:
    """``calibration`` must hold the calibration stage only. A project written before the stages
    were kept apart holds, after ``vebuild solve --recalibrate``, re-calibrated cameras inside
    ``calibration.cameras`` (each marked ``"recalibrated": true``) and re-calibrated markers in
    ``calibration.markers``: taken as priors they would count the same marks a second time, and
    the vanishing-point calibration they replaced is gone. Such a project is refused with a
    ProjectError at the first such camera's ``recalibrated`` field, saying to calibrate again."""
    for pid, rec in ((project.data.get("calibration") or {}).get("cameras") or {}).items():
        if isinstance(rec, Mapping) and rec.get("recalibrated"):
            raise ProjectError(project.path, json_path(["calibration", "cameras", pid, "recalibrated"]),
                               "this camera was re-calibrated by an older vebuild, which wrote `solve --recalibrate`'s "
                               "cameras and markers over the calibration's; the vanishing-point calibration is lost "
                               "and re-calibrating from these would count the same marks twice. Run `vebuild "
                               "calibrate` again (then `vebuild solve --recalibrate`)")


def cameras(project: Project) -> dict[str, ImageCamera]:
    """The cameras texturing, rendering, analyses and exports use (the final stage's): each photo's
    re-calibrated camera where the solution has one (``model_solution.cameras``), else its
    calibrated one; checked as :func:`cameras_from_calibration` checks them."""
    out = cameras_from_calibration(project)
    recal = recalibrated_cameras(project.data, project.data["calibration"]["cameras"])
    out.update(_cameras_from_records(project, recal, "model_solution"))
    return out


def _cameras_from_records(project: Project, records: Mapping[str, Any], key: str) -> dict[str, ImageCamera]:
    out = {}
    for p in project.data["photos"]:
        c = records.get(p["id"])
        if c is None:
            continue
        where = json_path([key, "cameras", p["id"]])
        K, R = np.asarray(c["K"], float), np.asarray(c["R"], float)
        _check_camera(project, where, K, R)
        cov = np.array([[np.inf if v is None else v for v in row] for row in c["covariance"]], float)
        C = np.asarray(c["position"]["value"], float)
        out[p["id"]] = ImageCamera(p["id"], K, R, C, p["width"], p["height"], covariance=cov,
                                   lens=_distortion_lens(project, where, c, K, int(p["width"]), int(p["height"])))
    return out


#: The division model's k1 (camera.py) beyond which no photographic lens lies: at k1 = −1 a
#: point at 45° off axis (|x_d| = 1) would be undistorted to infinity.
MAX_ABS_K1 = 1.0


#: The division model's k2 beyond which no photographic lens lies: a 150° fisheye's is some −0.06
#: (docs/lenses.md); at |k2| = 1 the term alone would halve a point's radius at 45° off axis.
MAX_ABS_K2 = 1.0


def _distortion_lens(project: Project, where: str, record: Mapping[str, Any], K: Array, width: int,
                     height: int) -> Lens:
    """The lens (k1, and k2 where the record has one) of a camera record's ``distortion``, checked:
    each within the range of real lenses, and the photo's corners within the lens's field (where the
    model still opens out and stays finite: past it the lens would show one point twice, or none)."""
    k1 = _distortion_k1(project, where, record)
    k2_record = (record.get("distortion") or {}).get("k2")
    if k2_record is None:
        return Lens(k1)
    k2 = k2_record["value"]
    if not (isinstance(k2, (int, float)) and np.isfinite(k2) and abs(k2) < MAX_ABS_K2):
        raise ProjectError(project.path, f"{where}.distortion.k2.value",
                           f"expected the division model's second term k2 as a number between −{MAX_ABS_K2:g} "
                           f"and {MAX_ABS_K2:g}, got {k2!r}")
    lens = Lens(k1, float(k2))
    corner = float(np.max(np.hypot(np.array([0.0, width]) - K[0, 2], np.array([[0.0], [height]]) - K[1, 2])))
    if not corner / K[0, 0] < lens.rim():
        raise ProjectError(project.path, f"{where}.distortion.k2.value",
                           f"expected a lens whose field reaches the photo's corners; k1 = {k1:g} with k2 = {k2:g} "
                           f"ends {lens.rim() * K[0, 0]:.0f} px from the principal point, short of the corners "
                           f"({corner:.0f} px): calibrate the photo again")
    return lens


def _distortion_k1(project: Project, where: str, record: Mapping[str, Any]) -> float:
    """k1 of a camera record's ``distortion`` (0 where it has none), checked."""
    d = record.get("distortion")
    if d is None:
        return 0.0
    k1 = d["k1"]["value"]
    if not (np.isfinite(k1) and abs(k1) < MAX_ABS_K1):
        raise ProjectError(project.path, f"{where}.distortion.k1.value",
                           f"expected the division model's k1 as a number between −{MAX_ABS_K1:g} and "
                           f"{MAX_ABS_K1:g}, got {k1!r}")
    return float(k1)


def _check_camera(project: Project, where: str, K: Array, R: Array) -> None:
    f, cx, cy = K[0, 0], K[0, 2], K[1, 2]
    tol = 1e-9 * abs(f)  # what rounding leaves of a pinhole matrix
    if not (abs(K[1, 1] - f) <= tol and abs(K[0, 1]) <= tol and abs(K[1, 0]) <= tol and list(K[2]) == [0, 0, 1]):
        raise ProjectError(project.path, f"{where}.K", "expected a pinhole matrix [[f, 0, cx], [0, f, cy], [0, 0, 1]] "
                           f"(square pixels, no skew), found {K.tolist()}")
    if not 1.0 <= f <= 1e7 or not (abs(cx) <= 1e6 and abs(cy) <= 1e6):
        raise ProjectError(project.path, f"{where}.K", f"expected a focal length from 1 to 1e7 pixels and a principal "
                           f"point within ±1e6 pixels, found f = {f:g}, (cx, cy) = ({cx:g}, {cy:g})")
    with np.errstate(all="ignore"):
        off = np.abs(R.T @ R - np.eye(3)).max()
        det = np.linalg.det(R)
    if not (off <= ROTATION_TOLERANCE and abs(det - 1.0) <= ROTATION_TOLERANCE):
        raise ProjectError(project.path, f"{where}.R", f"expected a rotation matrix (RᵀR = I within "
                           f"{ROTATION_TOLERANCE:g}, det R = +1), found one with |RᵀR − I| = {off:.3g} and "
                           f"det R = {det:.6g}; run `vebuild calibrate` again")


def photo_camera(project: Project, photo: str) -> ImageCamera:
    """The final camera of a photo (:func:`cameras`: re-calibrated where the solution has it, else
    calibrated), by id (or by its 1-based position in ``photos``), its
    :attr:`~vebuild.camera.ImageCamera.source` naming the photo (for errors about its size)."""
    ids = [p["id"] for p in project.data["photos"]]
    if photo not in ids and photo.isdigit() and 1 <= int(photo) <= len(ids):
        photo = ids[int(photo) - 1]
    if photo not in ids:
        raise ProjectError(project.path, "$.photos", f"no photo has the id {photo!r}; the photos are: "
                           + (", ".join(repr(i) for i in ids) or "none"))
    calibration = project.data.get("calibration") or {}
    left_out = (calibration.get("left_out") or {}).get(photo)
    if photo not in (calibration.get("cameras") or {}) and isinstance(left_out, Mapping):
        raise ProjectError(project.path, json_path(["calibration", "left_out", photo]),
                           f"photo {photo!r} has no camera: the calibration left it out ({left_out.get('reason')}); "
                           "do what that says and run `vebuild calibrate` again")
    if photo not in (calibration.get("cameras") or {}):
        raise ProjectError(project.path, "$.calibration.cameras",
                           f"photo {photo!r} has no calibrated camera; run `vebuild calibrate` (or `vebuild register`)")
    i = ids.index(photo)
    return dataclasses.replace(cameras(project)[photo],
                               source=f"$.photos[{i}] (photo {photo!r}: width × height)")


def view_camera(view: Mapping[str, Any], where: str = "") -> ImageCamera:
    """The camera of one view record (FORMAT.md, ``views``; validated by the project's schema):
    a position, a look direction (``direction``, or ``look_at`` a point), an optional roll, a
    horizontal field of view (``fov_deg``, default :data:`DEFAULT_FOV_DEG`) or a 35 mm-equivalent
    focal length (``focal_length_mm``, over a 36 mm wide frame), an image size; the principal point
    at the image centre. ``where``: its JSON path (``$.views[2]``), which the camera's
    :attr:`~vebuild.camera.ImageCamera.source` names."""
    C = np.asarray(view["position"], float)
    direction = np.asarray(view["look_at"], float) - C if "look_at" in view else np.asarray(view["direction"], float)
    R = look_rotation(direction, np.radians(view.get("roll_deg", 0.0)))
    w, h = int(view["width"]), int(view["height"])
    if "focal_length_mm" in view:
        f = view["focal_length_mm"] / FRAME_35MM_WIDTH_MM * w
    else:
        f = fov_to_focal(np.radians(view.get("fov_deg", DEFAULT_FOV_DEG)), w)
    K = intrinsic_matrix(f, w / 2, h / 2)
    return ImageCamera(view["name"], K, R, C, w, h,
                       source=f"{where or 'view ' + repr(view['name'])} (width × height)")


def find_view(project: Project, name: str) -> ImageCamera:
    """The camera of the view called ``name``; an error listing the views if there is none."""
    views = project.data.get("views", [])
    for i, v in enumerate(views):
        if v["name"] == name:
            return view_camera(v, f"$.views[{i}]")
    known = ", ".join(repr(v["name"]) for v in views) or "none (add them under \"views\")"
    raise ProjectError(project.path, "$.views", f"no view is called {name!r}; the views are: {known}")
