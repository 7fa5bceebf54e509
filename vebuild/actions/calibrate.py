"""Calibrate every photo of a project and place the cameras: ``vebuild calibrate``.

Reads the marks from the project document, runs :func:`calibrate_photo` per photo and
:func:`place_cameras` over all of them, and writes the results into ``data["calibration"]``
(see scenes/FORMAT.md). The caller saves the project.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from .. import __version__
from ..calibration.exif import exif_focal_prior
from ..calibration.photo import PhotoCalibration, calibrate_photo
from ..calibration.positions import PhotoInput, Placement, place_cameras
from ..errors import CalibrationError
from ..project import Project, canonical_input_hash, decode
from ..project.decode import check_reference_handles
from ..project.records import camera_record, json_values


def calibrate_photos(project: Project, progress: Callable[[Iterable], Iterable] = iter) -> dict[str, PhotoCalibration]:
    """Intrinsics and rotation of every photo that has vanishing segments."""
    settings = project.settings
    out = {}
    for photo in progress(project.data["photos"]):
        marks = decode.photo_marks(photo)
        if not marks.segments:
            continue
        out[photo["id"]] = calibrate_photo(
            marks.segments,
            photo["width"],
            photo["height"],
            photo=photo["id"],
            click_sigma_px=settings["click_sigma_px"],
            principal_point=marks.principal_point,
            principal_point_sigma_rel=settings["principal_point_sigma_rel"],
            focal=marks.focal,
            exif_focal=exif_focal_prior(photo, settings["exif_focal_sigma_rel"]),
        )
    return out


def calibrate_project(project: Project, progress: Callable[[Iterable], Iterable] = iter) -> dict[str, Any]:
    """Calibrate all photos, place the cameras, write and return ``project.data["calibration"]``.

    Raises CalibrationError naming the photo (or marker) whose marks are insufficient.
    """
    try:
        return _calibrate(project, progress)
    except CalibrationError as e:
        raise _located(project, e) from None


def _located(project: Project, e: CalibrationError) -> CalibrationError:
    """The same error, prefixed with the project file and the JSON path of the photo concerned."""
    ids = [p["id"] for p in project.data["photos"]]
    where = f"$.photos[{ids.index(e.photo)}] " if e.photo in ids else ""
    located = CalibrationError(e.photo, e.detail)
    located.args = (f"{project.path}: {where}{e}",)
    return located


def _calibrate(project: Project, progress: Callable[[Iterable], Iterable]) -> dict[str, Any]:
    data = project.data
    check_reference_handles(project)
    photos = calibrate_photos(project, progress)
    missing = [p["id"] for p in data["photos"] if p["id"] not in photos]
    if not photos:
        raise CalibrationError(None, "no photo has vanishing segments; mark segments along two world axes at least")
    known = decode.markers(data, "surveyed")
    refs = decode.reference_distances(data)
    shared = _pinned_handles(data)
    obs_of = {}
    for pid in photos:
        obs = decode.sightings(_photo(data, pid))
        obs.update(shared.get(pid, {}))
        obs_of[pid] = obs
    # A point seen once among the calibrated photos but again in a photo left for registration
    # waits for that photo; one seen once in the whole project stays, to be reported.
    in_project = _observation_counts(data)
    in_calibrated: dict[str, int] = {}
    for obs in obs_of.values():
        for n in obs:
            in_calibrated[n] = in_calibrated.get(n, 0) + 1
    waiting = {n for n, k in in_calibrated.items() if k < 2 and in_project.get(n, 0) >= 2 and n not in known}
    inputs = [PhotoInput(pid, cal.K, cal.R, cal.covariance,
                         {n: uv for n, uv in obs_of[pid].items() if n not in waiting})
              for pid, cal in photos.items()]
    placement = place_cameras(
        inputs,
        origin=data.get("origin_marker"),
        known_markers=known,
        distances=[d for d in refs if d.a not in waiting and d.b not in waiting],
        click_sigma_px=project.settings["click_sigma_px"],
    )
    result = _results(data, photos, placement)
    for pid in missing:
        result["warnings"].append(f"photo '{pid}' has no vanishing segments and is not calibrated: mark segments, "
                                  "or register it to the solved model (`vebuild register`, from 4 known points)")
    data["calibration"] = result
    return result


def _pinned_handles(data: dict[str, Any]) -> dict[str, dict[str, np.ndarray]]:
    """Fixed model pins seen in two photos or more, as extra shared points named 'node:handle'.

    A model vertex pinned in several photos ties them together exactly as a marker does, so the
    cameras can be placed from the origin marker and the model's pins alone.
    """
    pins = [p for p in (data.get("model") or {}).get("pins", []) if p.get("fixed", True)]
    photos_of: dict[str, set[str]] = {}
    for p in pins:
        photos_of.setdefault(f"{p['node']}:{p['handle']}", set()).add(p["photo"])
    out: dict[str, dict[str, np.ndarray]] = {}
    for p in pins:
        name = f"{p['node']}:{p['handle']}"
        if len(photos_of[name]) >= 2:
            out.setdefault(p["photo"], {})[name] = np.asarray(p["uv"], float)
    return out


def _observation_counts(data: dict[str, Any]) -> dict[str, int]:
    """In how many photos of the project each marker and each pinned handle is marked."""
    counts: dict[str, int] = {}
    for p in data["photos"]:
        for n in p.get("marker_observations") or {}:
            counts[n] = counts.get(n, 0) + 1
    seen = {(p["photo"], f"{p['node']}:{p['handle']}") for p in (data.get("model") or {}).get("pins", [])
            if p.get("fixed", True)}
    for _, n in seen:
        counts[n] = counts.get(n, 0) + 1
    return counts


def _photo(data: dict[str, Any], pid: str) -> dict[str, Any]:
    return next(p for p in data["photos"] if p["id"] == pid)


def _results(data: dict[str, Any], photos: dict[str, PhotoCalibration], placement: Placement) -> dict[str, Any]:
    cameras = {}
    warnings = []
    for pid, cal in photos.items():
        cam = placement.cameras[pid]
        cov = cam.covariance
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        marker_res = {n: json_values(d) for n, d in cam.marker_residuals_px.items() if ":" not in n}
        seg_res = np.concatenate(list(cal.segment_residuals_px.values()))
        mark = np.concatenate([np.asarray(d).ravel() for d in cam.marker_residuals_px.values()] or [np.zeros(0)])
        all_res = np.concatenate([seg_res, mark])
        vps = {}
        for a in cal.vanishing_points:
            # Report the vanishing point where the refined camera puts it.
            vp = cam.K @ cam.R[:, "xyz".index(a)]
            res = cal.segment_residuals_px[a]
            vps[a] = {"point": json_values(vp / np.linalg.norm(vp)), "residuals_px": json_values(res),
                      "rms_px": float(np.sqrt(np.mean(res**2)))}
        cameras[pid] = {
            "mode": cal.mode,
            "mode_reason": cal.mode_reason,
            "focal_source": cal.focal_source,
            **camera_record(cam.K, cam.R, cam.C, cov),
            "vanishing_points": vps,
            "marker_residuals_px": marker_res,
            "rms_px": float(np.sqrt(np.mean(all_res**2))),
        }
        exif = (_photo(data, pid).get("exif") or {}).get("focal_length_px")
        if exif and "exif" not in cal.focal_source:
            diff = (cam.K[0, 0] - exif) / exif
            cameras[pid]["exif_focal_check"] = {"exif_focal_px": float(exif), "difference_rel": float(diff)}
            if abs(diff) > 3 * max(sig[0] / cam.K[0, 0], 0.01):
                warnings.append(f"photo '{pid}': the focal length from the vanishing points differs from EXIF by "
                                f"{100 * diff:+.1f} % (more than 3σ): check the segments, or the photo was cropped")
        for n in cam.outliers:
            warnings.append(f"photo '{pid}': marker '{n}' lies {np.linalg.norm(cam.marker_residuals_px[n]):.1f} px "
                            "from where the other photos put it: check its placement")
    markers = {n: {"position": json_values(x), "sigma": json_values(np.sqrt(np.maximum(np.diag(c), 0.0)))}
               for n, (x, c) in placement.markers.items() if ":" not in n}
    distances = []
    for m in placement.distances:
        d = m.reference
        distances.append({"a": d.a, "b": d.b, "distance": d.distance, "sigma": d.sigma, "role": d.role,
                          "measured": m.measured, "measured_sigma": m.measured_sigma})
        if d.role == "check":
            z = (m.measured - d.distance) / np.hypot(m.measured_sigma, d.sigma)
            if abs(z) > 3:
                warnings.append(f"check distance {d.a}–{d.b}: measured {m.measured:.3f} m against {d.distance:.3f} m "
                                f"known ({z:+.1f}σ): the reconstruction disagrees with the tape")
    return {
        "software": f"vebuild {__version__}",
        "input_sha256": canonical_input_hash(data),
        "origin_marker": placement.origin,
        "variance_factor": placement.variance_factor,
        "cameras": cameras,
        "markers": markers,
        "reference_distances": distances,
        "warnings": warnings,
    }
