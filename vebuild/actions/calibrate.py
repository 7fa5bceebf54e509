"""Calibrate every photo of a project and place the cameras: ``vebuild calibrate``.

Reads the marks from the project document, runs :func:`calibrate_photo` per photo and
:func:`place_cameras` over all of them, and writes the results into ``data["calibration"]``
(see scenes/FORMAT.md). The caller saves the project.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from vebuild.calibration import positions
from vebuild.calibration.camera_groups import camera_groups
from vebuild.calibration.exif import exif_distortion_prior, exif_focal_prior
from vebuild.calibration.photo import PhotoCalibration, calibrate_photo
from vebuild.calibration.positions import PhotoInput, Placement, ReferenceDistance, place_cameras
from vebuild.calibration.shared_camera import GroupMember
from vebuild.calibration.single_photo import (
    FloorDistance,
    Origin,
    ScaleSource,
    SinglePhotoPlacement,
    camera_height_estimate,
    place_single_photo,
)
from vebuild.errors import CalibrationError
from vebuild.project import Project, decode, provenance
from vebuild.project.decode import check_reference_handles

from . import fixed_camera
from .calibration_results import (
    checked_after_solve,
    distortion_prior,
    exif_check_record,
    photo_of,
    results_record,
)
from .camera_group_records import GroupResult, add_group_records, calibrate_group, group_priors
from .orientation import leave_out_unoriented, misfit


def calibrate_photos(project: Project, progress: Callable[[Iterable], Iterable] = iter,
                     left_out: dict[str, CalibrationError] | None = None,
                     groups: dict[str, GroupResult] | None = None) -> dict[str, PhotoCalibration]:
    """Intrinsics and rotation of every photo that has vanishing segments.

    Photos of one camera (:mod:`vebuild.calibration.camera_groups`) are calibrated together,
    sharing f, c and k1 (:mod:`vebuild.calibration.shared_camera`); given ``groups``, each group's
    result is put there under its id. A photo whose marks cannot determine its camera raises its
    CalibrationError, or, given ``left_out``, is left out: its error is put there under its id and
    the others are calibrated.
    """
    settings = project.settings
    data = project.data
    marks_of = {p["id"]: decode.photo_marks(p) for p in data["photos"]}
    found = camera_groups(data["photos"], data.get("camera_groups") or [],
                          only={pid for pid, m in marks_of.items() if m.segments})
    group_of = {pid: g for g in found for pid in g.photos}
    done: dict[str, GroupResult] = {}
    out = {}
    for photo in progress(data["photos"]):
        pid = photo["id"]
        marks = marks_of[pid]
        if not marks.segments:
            continue
        try:
            g = group_of.get(pid)
            if g is not None:
                if g.id not in done:
                    by_id = {p["id"]: p for p in data["photos"]}
                    done[g.id] = calibrate_group(g, [GroupMember(m, _kwargs(by_id[m], marks_of[m], settings))
                                                     for m in g.photos])
                shared = done[g.id].shared
                if shared is not None and pid in shared.photos:
                    out[pid] = shared.photos[pid]
                    continue
                if shared is not None and pid in shared.failed:
                    raise shared.failed[pid]
            out[pid] = calibrate_photo(**_kwargs(photo, marks, settings))
        except CalibrationError as e:
            if left_out is None:
                raise
            left_out[pid] = e
    if groups is not None:
        groups.update(done)
    return out


def _kwargs(photo: dict[str, Any], marks: decode.PhotoMarks, settings: dict[str, Any]) -> dict[str, Any]:
    """What calibrate_photo is called with for a photo."""
    return dict(
        segments=marks.segments,
        width=photo["width"],
        height=photo["height"],
        photo=photo["id"],
        click_sigma_px=settings["click_sigma_px"],
        segment_sigma_px=decode.vanishing_segment_sigmas(photo, settings["click_sigma_px"]),
        principal_point=marks.principal_point,
        principal_point_sigma_rel=settings["principal_point_sigma_rel"],
        focal=marks.focal,
        exif_focal=exif_focal_prior(photo, settings["exif_focal_sigma_rel"]),
        # A lens profile where EXIF names a lens lensfun knows: the prior of the lens distortion,
        # refined by segments with middle points (the segments' straightness) where there are some.
        distortion=exif_distortion_prior(photo),
    )


def calibrate_project(project: Project, progress: Callable[[Iterable], Iterable] = iter) -> dict[str, Any]:
    """Calibrate all photos, place the cameras, write and return ``project.data["calibration"]``.

    Raises CalibrationError naming the photo (or marker) whose marks are insufficient.
    """
    # Stills of one fixed camera (frames of one video) are calibrated as one photo (fixed_camera.py).
    data, sets = fixed_camera.merged(project.data)
    try:
        if not sets:
            return _calibrate(project, progress)
        result = _calibrate(Project(project.path, data, project.loaded_sha256), progress)
    except CalibrationError as e:
        raise _located(project, e) from None
    fixed_camera.spread(result, sets)
    project.data["calibration"] = result
    provenance.stamp(project.data, "calibration")  # of the document itself, not of the merged one
    return result


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
    # A photo whose marks cannot determine its camera is left out, with its reason; the others are
    # calibrated and placed. Only where none can be is the project refused (with the first's error).
    left_out: dict[str, CalibrationError] = {}
    groups: dict[str, GroupResult] = {}
    photos = calibrate_photos(project, progress, left_out, groups)
    leave_out_unoriented(project, photos, left_out)
    missing = [p["id"] for p in data["photos"] if p["id"] not in photos and p["id"] not in left_out]
    if not photos and left_out:
        raise next(iter(left_out.values()))
    if not photos:
        name = project.path.name
        raise CalibrationError(None, "no photo has vanishing segments; mark segments along two world axes at least: "
                               f"`vebuild detect {name}` proposes them from the photos' straight edges (D in "
                               f"`vebuild edit {name}`), or draw them there by hand")
    known = decode.markers(data, "surveyed")
    refs = [d for d in decode.reference_distances(data) if not checked_after_solve(d)]
    floor = decode.floor_markers(data)
    shared = _pinned_handles(data)
    # A point seen once among the calibrated photos but again in a photo left for registration
    # waits for that photo; one seen once in the whole project stays, to be reported.
    in_project = _observation_counts(data)
    raw: dict[str, dict[str, np.ndarray]] = {}
    for pid in photos:
        raw[pid] = decode.sightings(photo_of(data, pid))
        raw[pid].update(shared.get(pid, {}))
    in_calibrated: dict[str, int] = {}
    for obs in raw.values():
        for n in obs:
            in_calibrated[n] = in_calibrated.get(n, 0) + 1
    waiting = {n for n, k in in_calibrated.items() if k < 2 and in_project.get(n, 0) >= 2 and n not in known}
    obs_of = {pid: {n: uv for n, uv in obs.items() if n not in waiting} for pid, obs in raw.items()}
    warnings: list[str] = []
    unplaced: dict[str, str] = {}

    # Photos that share a marker (or a pinned vertex) with another, or see a surveyed one, are placed
    # together (paper §2.1); a photo the joint placement cannot take is placed alone where it can be.
    joint_names = {n for n, k in in_calibrated.items() if (k >= 2 or n in known) and n not in waiting}
    joint = [pid for pid in photos if any(n in joint_names for n in obs_of[pid])]
    placement, joint_error = None, None
    while len(joint) >= 2:
        try:
            said = len(warnings)
            placement = _place_jointly(project, photos, joint, obs_of, joint_names, known, refs, floor, warnings,
                                       group_priors(groups))
            turned = misfit(placement, obs_of) if len(joint) > 2 else None
            if turned is not None:  # placed turned: left out, and the others placed again without it
                left_out[turned[0]] = CalibrationError(turned[0], turned[1])
                del photos[turned[0]], warnings[said:]
                joint.remove(turned[0])
                placement = None
                continue
            break
        except CalibrationError as e:
            if e.photo in joint and len(joint) > 2:
                unplaced[e.photo] = e.detail
                joint.remove(e.photo)
                continue
            joint_error = _after_leaving_out(e, unplaced)
            break
    jointly = set(placement.cameras) if placement is not None else set()
    alone: dict[str, SinglePhotoPlacement] = {}
    single = len(photos) == 1
    origin_name = placement.origin if placement is not None else data.get("origin_marker")
    for pid in photos:
        if pid in jointly:
            continue
        sources = _scale_sources(data, pid, obs_of[pid], refs, floor, with_floor_distances=True)
        if not sources and not single:
            own_error = joint_error is not None and pid in joint and joint_error.photo in (None, pid)
            unplaced.setdefault(pid, joint_error.detail if own_error and joint_error is not None else
                                "it shares no two markers with a placed photo and has no scale of its own, so it "
                                "cannot be placed: mark two markers that placed photos also show (or give it a "
                                "scale: its camera_height, or a known length in it)")
            continue
        try:
            origin = _single_origin(pid, obs_of[pid], origin_name, placement is not None)
            if origin.marker is None and origin_name is not None and single:
                warnings.append(f"photo '{pid}' does not show the origin marker '{origin_name}', so its origin is "
                                f"{origin.describe()}; mark '{origin_name}' in it to measure from that point")
            alone[pid] = _place_alone(project, photos[pid], pid, origin, sources, obs_of[pid], floor)
            unplaced.pop(pid, None)  # the joint placement could not take it; alone, it is placed
            placed_jointly = set(placement.markers) if placement is not None else set()
            for n in sorted(obs_of[pid]):
                if n != origin.marker and n not in floor and n not in placed_jointly and ":" not in n:
                    warnings.append(f"photo '{pid}': marker '{n}' is not placed: one photo places only markers on "
                                    "the floor; if it lies on the floor, tick its 'on the floor' box in the "
                                    "Calibration tab, or else mark it in a second photo")
        except CalibrationError as e:
            unplaced[pid] = e.detail  # calibrated, not placed: what it determines is kept, and the fix said
    if not jointly and not alone and not single:
        if joint_error is not None:
            raise joint_error
        pid = next(iter(unplaced))
        raise CalibrationError(pid, unplaced[pid])
    markers_at_origin = {a.origin.marker for a in alone.values()}
    if len(alone) > 1 and not jointly and (len(markers_at_origin) > 1 or None in markers_at_origin):
        warnings.append("photos " + ", ".join(f"'{p}'" for p in alone) + " are each placed alone, in frames with "
                        "origins of their own: their positions cannot be compared; mark the same origin marker on "
                        "the floor in each")
    result = results_record(data, photos, placement, alone, unplaced, warnings, floor,
                            project.settings["click_sigma_px"])
    ids = [p["id"] for p in data["photos"]]
    for pid, err in left_out.items():
        result.setdefault("left_out", {})[pid] = {"reason": err.detail}
        result["warnings"].append(f"photo '{pid}' is left out of the calibration, the other photos calibrated "
                                  f"without it: {err.detail}\ndetails: $.photos[{ids.index(pid)}]")
    add_group_records(result, groups, exif_check_record)
    for pid in missing:
        result["warnings"].append(f"photo '{pid}' has no vanishing segments and is not calibrated: mark segments, "
                                  "or register it to the solved model (`vebuild register`, from 4 known points)")
    data["calibration"] = result
    provenance.stamp(data, "calibration")  # what it was computed from (vebuild.project.provenance)
    return result


def _after_leaving_out(e: CalibrationError, left_out: dict[str, str]) -> CalibrationError:
    """The joint placement's error once photos were left out of it: the same error, saying which
    photos were left out and why (what is missing may be in them: a scale distance's marker)."""
    if not left_out or e.photo in left_out:
        return e
    why = "; ".join(f"'{pid}': {detail}" for pid, detail in left_out.items())
    return CalibrationError(e.photo, f"{e.detail} (with photo(s) {', '.join(repr(p) for p in left_out)} left out of "
                            f"the joint placement, which could not place them: {why})")


def _place_jointly(project: Project, photos: dict[str, PhotoCalibration], joint: list[str],
                   obs_of: dict[str, dict[str, np.ndarray]], joint_names: set[str], known: dict[str, np.ndarray],
                   refs: list[ReferenceDistance], floor: set[str], warnings: list[str],
                   groups: list[positions.CameraGroupPrior]) -> Placement:
    """The photos ``joint`` placed together (paper §2.1), each one's own scale (camera height, known
    lengths) a residual on its camera's height. A marker seen by one of them only is left out (it
    is a floor marker its photo places alone, or a warning)."""
    data = project.data
    click = project.settings["click_sigma_px"]
    counts: dict[str, int] = {}
    for pid in joint:
        for n in obs_of[pid]:
            counts[n] = counts.get(n, 0) + 1
    inputs, heights = [], {}
    for pid in joint:
        cal = photos[pid]
        marks = {}
        for n, uv in obs_of[pid].items():
            if counts[n] >= 2 or n in known:
                marks[n] = uv
            elif n not in floor and ":" not in n:
                warnings.append(f"photo '{pid}': marker '{n}' is marked in this photo only, so it is not placed; "
                                "mark it in a second photo (or, if it lies on the floor, tick its 'on the floor' "
                                "box in the Calibration tab)")
        cov, k1, k1_sigma = distortion_prior(cal)
        inputs.append(PhotoInput(pid, cal.K, cal.R, cov, marks, k1, k1_sigma, k2=cal.k2,
                                 corner_px=0.5 * float(np.hypot(cal.width, cal.height))))
        sources = _scale_sources(data, pid, obs_of[pid], refs, floor, with_floor_distances=False)
        if sources:
            h, sigma, _ = camera_height_estimate(pid, cal.K, cal.R, cov, sources, k1=k1, k2=cal.k2,
                                                  click_sigma_px=click)
            heights[pid] = (h, sigma)
    seen = {n for p in inputs for n in p.markers} | set(known)
    usable = [d for d in refs if d.a in seen and d.b in seen]
    scales = [d for d in refs if d.role == "scale"]
    if scales and not any(d.role == "scale" for d in usable) and not heights and not set(known) - {
            data.get("origin_marker")}:
        ends = sorted({n for d in scales for n in (d.a, d.b) if n not in seen})
        where = "; ".join(f"'{n}' is marked in " + (", ".join(f"'{pid}'" for pid in obs_of if n in obs_of[pid])
                                                     or "no calibrated photo") for n in ends)
        raise CalibrationError(None, "nothing fixes the metric scale: the scale distance(s) "
                               + ", ".join(f"{d.a}–{d.b}" for d in scales) + " join markers that the joint "
                               f"placement cannot place ({where}); mark them in two or more of the photos that see "
                               "the origin, or tie the photos that show them to those with shared markers")
    placement = place_cameras(
        inputs,
        origin=data.get("origin_marker"),
        known_markers=known,
        distances=usable,
        click_sigma_px=click,
        camera_heights=heights,
        groups=groups,
    )
    warnings += placement.warnings
    return placement


def _scale_sources(data: dict[str, Any], pid: str, obs: dict[str, np.ndarray], refs: list[ReferenceDistance],
                   floor: set[str], with_floor_distances: bool) -> list[ScaleSource]:
    """A photo's own scale: its camera height, the known lengths clicked in it, and (placed alone)
    the scale distances between two floor markers it shows."""
    ids = [p["id"] for p in data["photos"]]
    out: list[ScaleSource] = []
    h = decode.photo_camera_height(photo_of(data, pid), ids.index(pid))
    if h is not None:
        out.append(h)
    out += decode.known_lengths(data, pid)
    if with_floor_distances:
        for i, d in enumerate(refs):
            if d.role == "scale" and d.a in floor and d.b in floor and d.a in obs and d.b in obs:
                out.append(FloorDistance(d.a, d.b, obs[d.a], obs[d.b], d.distance, d.sigma,
                                         f"$.reference_distances[{i}]"))
    return out


def _single_origin(pid: str, obs: dict[str, np.ndarray], origin_name: str | None, joint_exists: bool) -> Origin:
    """The floor point a photo placed alone puts at the origin: the origin marker where it shows it,
    else the floor point below its camera. Beside a joint placement only the joint's origin marker
    will do (another origin would be another frame)."""
    if origin_name is not None and origin_name in obs:
        return Origin(origin_name, obs[origin_name])
    if joint_exists:
        raise CalibrationError(pid, f"it does not show the origin marker '{origin_name}' and shares no two markers "
                               f"with the placed photos, so it cannot be placed in their frame: mark '{origin_name}' "
                               "in it (or two markers that placed photos also show)")
    return Origin()


def _place_alone(project: Project, cal: PhotoCalibration, pid: str, origin: Origin, sources: list[ScaleSource],
                 obs: dict[str, np.ndarray], floor: set[str]) -> SinglePhotoPlacement:
    cov, k1, _ = distortion_prior(cal)
    on_floor = {n: uv for n, uv in obs.items() if n in floor and n != origin.marker}
    return place_single_photo(pid, cal.K, cal.R, cov, origin, sources, on_floor, k1=k1, k2=cal.k2,
                              click_sigma_px=project.settings["click_sigma_px"])


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
