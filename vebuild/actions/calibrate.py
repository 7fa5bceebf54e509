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
from ..calibration import positions
from ..calibration.camera_groups import camera_groups
from ..calibration.exif import exif_distortion_prior, exif_focal_prior
from ..calibration.photo import EXIF_DISAGREEMENT_SIGMAS, PhotoCalibration, calibrate_photo
from ..calibration.positions import PhotoInput, PlacedCamera, Placement, ReferenceDistance, place_cameras
from ..calibration.priors import ExifCheck
from ..calibration.shared_camera import GroupMember
from ..calibration.single_photo import (
    FloorDistance,
    Origin,
    ScaleSource,
    SinglePhotoPlacement,
    camera_height_estimate,
    floor_point,
    place_single_photo,
)
from ..console.tables import exif_check_words, failed_check_words
from ..constants import CHECK_FAIL_SIGMAS, OUTLIER_SIGMAS
from ..errors import CalibrationError
from ..project import Project, canonical_input_hash, decode, provenance
from ..project.decode import check_reference_handles
from ..project.records import camera_record, distortion_record, json_values, value_sigma
from ..project.units import METRES, RELATIVE
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
        raise CalibrationError(None, "no photo has vanishing segments; mark segments along two world axes at least")
    known = decode.markers(data, "surveyed")
    refs = [d for d in decode.reference_distances(data) if not checked_after_solve(d)]
    floor = decode.floor_markers(data)
    shared = _pinned_handles(data)
    # A point seen once among the calibrated photos but again in a photo left for registration
    # waits for that photo; one seen once in the whole project stays, to be reported.
    in_project = _observation_counts(data)
    raw: dict[str, dict[str, np.ndarray]] = {}
    for pid in photos:
        raw[pid] = decode.sightings(_photo(data, pid))
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
            origin = _single_origin(data, pid, obs_of[pid], origin_name, floor, placement is not None)
            alone[pid] = _place_alone(project, photos[pid], pid, origin, sources, obs_of[pid], floor)
            unplaced.pop(pid, None)  # the joint placement could not take it; alone, it is placed
            placed_jointly = set(placement.markers) if placement is not None else set()
            for n in sorted(obs_of[pid]):
                if n != origin.marker and n not in floor and n not in placed_jointly and ":" not in n:
                    warnings.append(f"photo '{pid}': marker '{n}' is not placed: one photo places only markers on "
                                    "the floor; mark it on_floor if it lies on the floor, or mark it in a second "
                                    "photo")
        except CalibrationError as e:
            if single:
                raise
            unplaced[pid] = e.detail
    if not jointly and not alone:
        if joint_error is not None:
            raise joint_error
        pid = next(iter(unplaced))
        raise CalibrationError(pid, unplaced[pid])
    markers_at_origin = {a.origin.marker for a in alone.values()}
    if len(alone) > 1 and not jointly and (len(markers_at_origin) > 1 or None in markers_at_origin):
        warnings.append("photos " + ", ".join(f"'{p}'" for p in alone) + " are each placed alone, in frames with "
                        "origins of their own: their positions cannot be compared; mark the same origin marker on "
                        "the floor in each")
    result = _results(data, photos, placement, alone, unplaced, warnings, floor, project.settings["click_sigma_px"])
    ids = [p["id"] for p in data["photos"]]
    for pid, err in left_out.items():
        result.setdefault("left_out", {})[pid] = {"reason": err.detail}
        result["warnings"].append(f"photo '{pid}' is left out of the calibration ($.photos[{ids.index(pid)}]), the "
                                  f"other photos calibrated without it: {err.detail}")
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


def checked_after_solve(d: ReferenceDistance) -> bool:
    """A check distance with an end on a model vertex (``node:handle``): the calibration does not
    place model vertices (a pinned one only ties photos together), so it leaves the distance out of
    its own checks; ``vebuild solve`` measures it on the final model. A scale distance on a vertex
    stays: placement uses it where the vertex is pinned in two calibrated photos, and ``vebuild solve
    --recalibrate`` uses it in any case."""
    return d.role == "check" and (":" in d.a or ":" in d.b)


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
                                "mark it in a second photo (or mark it on_floor if it lies on the floor)")
        cov, k1, k1_sigma = _distortion_prior(cal)
        inputs.append(PhotoInput(pid, cal.K, cal.R, cov, marks, k1, k1_sigma,
                                 corner_px=0.5 * float(np.hypot(cal.width, cal.height))))
        sources = _scale_sources(data, pid, obs_of[pid], refs, floor, with_floor_distances=False)
        if sources:
            h, sigma, _ = camera_height_estimate(pid, cal.K, cal.R, cov, sources, k1=k1, click_sigma_px=click)
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


def _distortion_prior(cal: PhotoCalibration) -> tuple[np.ndarray, float, float]:
    """The covariance placement holds the photo by, its k1 and k1's 1σ: 7×7 with k1 last where the
    calibration estimated k1 (then placement refines it), else 6×6 with k1 held."""
    k1, k1_sigma, cov7 = float(cal.k1), float(cal.k1_sigma), cal.covariance_k1
    if np.all(np.isfinite(cov7)) and cov7[6][6] > 0:
        return np.asarray(cov7, float), k1, k1_sigma
    return cal.covariance, k1, k1_sigma


def vanishing_point_prior(cal: PhotoCalibration, height: tuple[float, float] | None) -> dict[str, Any]:
    """What held a jointly placed photo's camera before any marker (FORMAT.md
    ``vanishing_point_prior``): its vanishing-point K, R and covariance over (f, cx, cy, ω), its
    k1 where the vanishing points estimated it, and of its position only the height its own scale
    gave (camera height, known lengths); null where nothing but the markers held it. A
    re-calibration (``vebuild solve --recalibrate``) holds the photo by this alone, since the
    markers, pins and scale distances the placement used are in it again."""
    cov = np.full((9, 9), np.nan)
    cov[:6, :6] = cal.covariance
    if height is not None:
        cov[:6, 8] = cov[8, :6] = 0.0
        cov[8, 8] = height[1] ** 2
    out: dict[str, Any] = {"K": json_values(cal.K), "R": json_values(cal.R),
                           "covariance": [[None if not np.isfinite(v) else float(v) for v in row] for row in cov]}
    prior, k1, k1_sigma = _distortion_prior(cal)
    if prior.shape == (7, 7):
        out["k1"] = value_sigma(k1, float(np.sqrt(prior[6, 6])))
    return out


def _scale_sources(data: dict[str, Any], pid: str, obs: dict[str, np.ndarray], refs: list[ReferenceDistance],
                   floor: set[str], with_floor_distances: bool) -> list[ScaleSource]:
    """A photo's own scale: its camera height, the known lengths clicked in it, and (placed alone)
    the scale distances between two floor markers it shows."""
    ids = [p["id"] for p in data["photos"]]
    out: list[ScaleSource] = []
    h = decode.photo_camera_height(_photo(data, pid), ids.index(pid))
    if h is not None:
        out.append(h)
    out += decode.known_lengths(data, pid)
    if with_floor_distances:
        for i, d in enumerate(refs):
            if d.role == "scale" and d.a in floor and d.b in floor and d.a in obs and d.b in obs:
                out.append(FloorDistance(d.a, d.b, obs[d.a], obs[d.b], d.distance, d.sigma,
                                         f"$.reference_distances[{i}]"))
    return out


def _single_origin(data: dict[str, Any], pid: str, obs: dict[str, np.ndarray], origin_name: str | None,
                   floor: set[str], joint_exists: bool) -> Origin:
    """The floor point a photo placed alone puts at the origin: the origin marker where it shows it;
    with no origin marker chosen, its first floor marker; else the meeting of its first x and first y
    vanishing segments' lines. Beside a joint placement only the joint's origin marker will do
    (another origin would be another frame)."""
    if origin_name is not None and origin_name in obs:
        return Origin(origin_name, obs[origin_name])
    if joint_exists:
        raise CalibrationError(pid, f"it does not show the origin marker '{origin_name}' and shares no two markers "
                               f"with the placed photos, so it cannot be placed in their frame: mark '{origin_name}' "
                               "in it (or two markers that placed photos also show)")
    if origin_name is None:
        on_floor = sorted(n for n in obs if n in floor)
        if on_floor:
            return Origin(on_floor[0], obs[on_floor[0]])
    segs = decode.photo_marks(_photo(data, pid)).segments
    if len(segs.get("x", [])) and len(segs.get("y", [])):
        # A segment may be a polyline (its middle points say how straight the edge is): its line is
        # that of its end points.
        return Origin(None, np.array([np.asarray(segs[a][0], float).reshape(-1, 2)[[0, -1]].ravel() for a in "xy"]))
    what = f"the origin marker '{origin_name}'" if origin_name else "a marker on the floor"
    raise CalibrationError(pid, f"nothing in it fixes the world's origin: it shows no origin marker and no x and y "
                           f"vanishing segments; mark {what} in it (the origin lies on the floor)")


def _place_alone(project: Project, cal: PhotoCalibration, pid: str, origin: Origin, sources: list[ScaleSource],
                 obs: dict[str, np.ndarray], floor: set[str]) -> SinglePhotoPlacement:
    cov, k1, _ = _distortion_prior(cal)
    on_floor = {n: uv for n, uv in obs.items() if n in floor and n != origin.marker}
    return place_single_photo(pid, cal.K, cal.R, cov, origin, sources, on_floor, k1=k1,
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


def _photo(data: dict[str, Any], pid: str) -> dict[str, Any]:
    return next(p for p in data["photos"] if p["id"] == pid)


def _floor_markers_seen_once(data: dict[str, Any], placement: Placement | None,
                             floor: set[str]) -> dict[str, tuple[str, np.ndarray]]:
    """Floor markers that exactly one jointly placed photo shows (and the joint did not place):
    name → (that photo, its click)."""
    if placement is None:
        return {}
    seen: dict[str, list[tuple[str, np.ndarray]]] = {}
    for pid in placement.cameras:
        for n, uv in decode.sightings(_photo(data, pid)).items():
            if n in floor and n not in placement.markers:
                seen.setdefault(n, []).append((pid, uv))
    return {n: v[0] for n, v in seen.items() if len(v) == 1}


def _results(data: dict[str, Any], photos: dict[str, PhotoCalibration], placement: Placement | None,
             alone: dict[str, SinglePhotoPlacement], unplaced: dict[str, str], warnings: list[str],
             floor: set[str], click: float) -> dict[str, Any]:
    cameras = {}
    ids = [p["id"] for p in data["photos"]]
    placed: dict[str, PlacedCamera | SinglePhotoPlacement] = dict(placement.cameras) if placement else {}
    placed.update(alone)
    for pid in [i for i in ids if i in placed]:
        cal, cam = photos[pid], placed[pid]
        cov = cam.covariance
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        marker_res = {n: json_values(d) for n, d in cam.marker_residuals_px.items() if ":" not in n}
        seg_res = np.concatenate([cal.kept_residuals_px(a) for a in cal.segment_residuals_px])
        mark = np.concatenate([np.asarray(d).ravel() for d in cam.marker_residuals_px.values()] or [np.zeros(0)])
        all_res = np.concatenate([seg_res, mark])
        vps = {}
        for a in cal.vanishing_points:
            # Report the vanishing point where the refined camera puts it.
            vp = cam.K @ cam.R[:, "xyz".index(a)]
            res, kept = cal.segment_residuals_px[a], cal.kept_residuals_px(a)
            kept = kept if len(kept) else res  # an axis left out whole: all its segments'
            vps[a] = {"point": json_values(vp / np.linalg.norm(vp)), "residuals_px": json_values(res),
                      "rms_px": float(np.sqrt(np.mean(kept**2)))}
            if a in cal.rejected_segments:  # left out as not meeting at the point (calibration/robust.py)
                vps[a]["rejected"] = [{"segment": r.index, "misfit_sigmas": r.misfit_sigmas, "reason": r.reason}
                                      for r in cal.rejected_segments[a]]
        # A photo whose lens was neither estimated nor given is a pinhole: no record (FORMAT.md).
        distortion = None
        if cal.k1_source != "none" or cam.k1 != 0.0:
            distortion = distortion_record(cam.K, cal.width, cal.height, cam.k1, cam.k1_sigma, cal.k1_source)
        cameras[pid] = {
            "mode": cal.mode,
            "mode_reason": cal.mode_reason,
            "focal_source": cal.focal_source,
            **camera_record(cam.K, cam.R, cam.C, cov, distortion),
            "vanishing_points": vps,
            "marker_residuals_px": marker_res,
            "rms_px": float(np.sqrt(np.mean(all_res**2))),
        }
        if isinstance(cam, SinglePhotoPlacement):
            cameras[pid]["placement"] = {
                "how": "alone", "origin": cam.origin.describe(), "scale": cam.scale_source,
                "lengths": "relative" if cam.relative else "metres",
                (RELATIVE if cam.relative else METRES).key("camera_height"): value_sigma(
                    cam.camera_height, cam.camera_height_sigma if not cam.relative else None),
                "scale_estimates": [{"source": e.describe(), "camera_height_m": value_sigma(e.height, e.sigma)}
                                    for e in cam.estimates]}
            warnings += cam.warnings
            if cam.relative:
                warnings.append(f"photo '{pid}': nothing gives the scale, so lengths are relative: the camera's "
                                "height above the floor is taken as 1 and every position is in that unit; give its "
                                f"camera_height ($.photos[{ids.index(pid)}].camera_height), a known length in it "
                                "($.known_lengths) or a reference distance between two markers on the floor")
        else:
            cameras[pid]["placement"] = {"how": "joint", "origin": f"marker '{placement.origin}'" if placement else "",
                                         "lengths": "metres"}
            cameras[pid]["vanishing_point_prior"] = vanishing_point_prior(
                cal, placement.camera_heights.get(pid) if placement else None)
        if cal.exif_check is not None:
            cameras[pid]["exif_focal_check"] = exif_check_record(cal.exif_check)
        for n in getattr(cam, "outliers", []):
            away = getattr(cam, "outlier_offsets_px", {}).get(n, np.linalg.norm(cam.marker_residuals_px[n]))
            warnings.append(f"photo '{pid}': marker '{n}' lies {away:.1f} px from where the other photos put it "
                            f"(beyond {OUTLIER_SIGMAS:g}σ of the click noise and the placement's uncertainty "
                            "there): check its placement")
    all_markers: dict[str, tuple[np.ndarray, np.ndarray]] = dict(placement.markers) if placement else {}
    for n, (pid, uv) in sorted(_floor_markers_seen_once(data, placement, floor).items()):
        pc = placement.cameras[pid] if placement else None
        if pc is not None and n not in all_markers:
            # One photo of the joint placement shows it: placed from that photo alone, on the floor.
            try:
                all_markers[n] = floor_point(pid, pc.K, pc.R, pc.C, pc.covariance, uv, k1=pc.k1,
                                             click_sigma_px=click, what=f"marker '{n}' (on the floor)")
            except CalibrationError as e:
                warnings.append(f"{e} (it is not placed)")
    placed_by: dict[str, SinglePhotoPlacement] = {}
    for sp in alone.values():
        for n, xc in [*([(sp.origin.marker, (np.zeros(3), np.zeros((3, 3))))] if sp.origin.marker else []),
                      *sp.markers.items()]:
            if n not in all_markers:
                all_markers[n] = xc
                placed_by[n] = sp
    markers = {n: {"position": json_values(x), "sigma": json_values(np.sqrt(np.maximum(np.diag(c), 0.0)))}
               for n, (x, c) in sorted(all_markers.items()) if ":" not in n}
    distances = []
    failed: list[dict[str, Any]] = []
    measured = {(m.reference.a, m.reference.b): (m.measured, m.measured_sigma)
                for m in (placement.distances if placement else [])}
    after_solve = []
    for d in decode.reference_distances(data):
        if checked_after_solve(d):
            after_solve.append({"a": d.a, "b": d.b, "distance": d.distance, "sigma": d.sigma, "role": d.role})
            continue
        if (d.a, d.b) in measured:
            dist, dist_sigma = measured[(d.a, d.b)]
        elif d.a in placed_by and placed_by.get(d.b) is placed_by[d.a]:
            dist, dist_sigma = placed_by[d.a].distance(d.a, d.b)
        else:
            continue
        relative = d.a in placed_by and placed_by[d.a].relative
        distances.append({"a": d.a, "b": d.b, "distance": d.distance, "sigma": d.sigma, "role": d.role,
                          "measured": dist, "measured_sigma": json_values(dist_sigma),
                          **({"lengths": "relative"} if relative else {})})
        if d.role == "check" and relative:
            warnings.append(f"check distance {d.a}–{d.b}: measured {dist:.3f} in units of the camera's height, not "
                            "metres (no scale was given), so it is not compared with the tape; make it a scale "
                            "distance (role \"scale\") to give the photo its scale")
        elif d.role == "check":
            z = (dist - d.distance) / np.hypot(dist_sigma, d.sigma)
            if abs(z) > CHECK_FAIL_SIGMAS:
                failed.append({"a": d.a, "b": d.b, "distance": d.distance, "measured": dist,
                               "measured_sigma": float(dist_sigma), "sigmas": float(z),
                               "limit_sigmas": CHECK_FAIL_SIGMAS})
                warnings.append(f"FAILED {failed_check_words(failed[-1])}: the calibration fails this check "
                                "(calibration.failed_checks); look for a photo placed wrongly, or a wrong tape")
            elif abs(z) > 3:
                warnings.append(f"check distance {d.a}–{d.b}: measured {dist:.3f} m against {d.distance:.3f} m "
                                f"known ({z:+.1f}σ): the reconstruction disagrees with the tape")
    unplaced_records = {}
    for pid in [i for i in ids if i in unplaced]:
        cal = photos[pid]
        sig = np.sqrt(np.maximum(np.diag(cal.covariance), 0.0))
        ypr, ypr_sig = cal.ypr()
        unplaced_records[pid] = {"reason": unplaced[pid], "mode": cal.mode, "mode_reason": cal.mode_reason,
                                 "focal_source": cal.focal_source, "K": json_values(cal.K), "R": json_values(cal.R),
                                 "focal_px": value_sigma(cal.f, sig[0]),
                                 "principal_point": value_sigma(cal.principal_point, sig[1:3]),
                                 "ypr_deg": value_sigma(np.degrees(ypr), np.degrees(ypr_sig))}
        if cal.exif_check is not None:
            unplaced_records[pid]["exif_focal_check"] = exif_check_record(cal.exif_check)
        warnings.append(f"photo '{pid}' is calibrated (its focal length, principal point and rotation are kept under "
                        f"calibration.unplaced) but not placed: {unplaced[pid]}")
    # One check per camera: a camera group's photos share their group's check (one object), so it
    # is said once, naming them all.
    contradicted: dict[int, tuple[ExifCheck, list[str]]] = {}
    for pid in [i for i in ids if i in photos]:
        check = photos[pid].exif_check
        if check is not None and check.sigmas > EXIF_DISAGREEMENT_SIGMAS:
            contradicted.setdefault(id(check), (check, []))[1].append(pid)
    for check, pids in contradicted.values():
        cal = photos[pids[0]]
        # Beyond the limit EXIF is never combined; the user's focal length, where given, still is.
        used = ("EXIF is not combined, the focal length is from the vanishing points alone"
                if cal.focal_source == "vanishing points" else "EXIF is not used")
        who = f"photo '{pids[0]}'" if len(pids) == 1 else \
            "photos " + ", ".join(f"'{p}'" for p in pids) + " (one camera group)"
        warnings.append(f"{who}: {exif_check_words(exif_check_record(check))}; {used}: check the "
                        "segments, or the photo was cropped or zoomed digitally")
    relative = any(a.relative for a in alone.values())
    origin = placement.origin if placement else next((a.origin.marker for a in alone.values()), None)
    return {
        "software": f"vebuild {__version__}",
        "input_sha256": canonical_input_hash(data),
        "origin_marker": origin,
        "origin": _origin_text(placement, alone),
        "lengths": "relative" if relative else "metres",
        "variance_factor": placement.variance_factor if placement else 1.0,
        "cameras": cameras,
        "markers": markers,
        "reference_distances": distances,
        "checked_after_solve": after_solve,
        **({"failed_checks": failed} if failed else {}),
        "unplaced": unplaced_records,
        "warnings": warnings,
    }


def exif_check_record(check: ExifCheck) -> dict[str, Any]:
    """The record of EXIF's focal length against the vanishing points' alone (FORMAT.md
    ``exif_focal_check``): EXIF relative to the vanishing points' estimate, one sign everywhere."""
    return {"exif_focal_px": float(check.exif.value), "exif_sigma_px": float(check.exif.sigma),
            "lines_focal_px": value_sigma(check.lines_px, check.lines_sigma_px),
            "difference_rel": float(check.difference_rel), "sigma_rel": float(check.sigma_rel),
            "sigmas": float(check.sigmas), "limit_sigmas": EXIF_DISAGREEMENT_SIGMAS, "combined": check.combined,
            "source": check.exif.source}


def _origin_text(placement: Placement | None, alone: dict[str, SinglePhotoPlacement]) -> str:
    """What the world's origin is: the joint placement's origin marker, or each photo placed alone's
    origin (once, where they all share it)."""
    if placement is not None:
        return f"marker '{placement.origin}'"
    texts = {a.origin.describe() for a in alone.values()}
    if len(texts) == 1:
        return texts.pop()
    return "; ".join(f"photo '{pid}': {a.origin.describe()}" for pid, a in alone.items())
