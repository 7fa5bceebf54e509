"""The calibration's record (``calibration`` in the project file, scenes/FORMAT.md): cameras, markers,
measured distances, failed checks and warnings, from what :mod:`.calibrate` computed."""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild import __version__
from vebuild.calibration.photo import EXIF_DISAGREEMENT_SIGMAS, PhotoCalibration
from vebuild.calibration.positions import PlacedCamera, Placement, ReferenceDistance
from vebuild.calibration.priors import ExifCheck
from vebuild.calibration.single_photo import SinglePhotoPlacement, floor_point
from vebuild.console.tables import exif_check_words, failed_check_words
from vebuild.constants import CHECK_FAIL_SIGMAS, OUTLIER_SIGMAS
from vebuild.errors import CalibrationError
from vebuild.project import canonical_input_hash, decode
from vebuild.project.records import camera_record, distortion_record, json_values, value_sigma
from vebuild.project.units import METRES, RELATIVE


def distortion_prior(cal: PhotoCalibration) -> tuple[np.ndarray, float, float]:
    """The covariance placement holds the photo by, its k1 and k1's 1σ: 7×7 with k1 last where the
    calibration estimated k1 (then placement refines it), else 6×6 with k1 held."""
    k1, k1_sigma, cov7 = float(cal.k1), float(cal.k1_sigma), cal.covariance_k1
    if np.all(np.isfinite(cov7)) and cov7[6][6] > 0:
        return np.asarray(cov7, float), k1, k1_sigma
    return cal.covariance, k1, k1_sigma


def checked_after_solve(d: ReferenceDistance) -> bool:
    """A check distance with an end on a model vertex (``node:handle``): the calibration does not
    place model vertices (a pinned one only ties photos together), so it leaves the distance out of
    its own checks; ``vebuild solve`` measures it on the final model. A scale distance on a vertex
    stays: placement uses it where the vertex is pinned in two calibrated photos, and ``vebuild solve
    --recalibrate`` uses it in any case."""
    return d.role == "check" and (":" in d.a or ":" in d.b)


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
    prior, k1, k1_sigma = distortion_prior(cal)
    if prior.shape == (7, 7):
        out["k1"] = value_sigma(k1, float(np.sqrt(prior[6, 6])))
    return out


def photo_of(data: dict[str, Any], pid: str) -> dict[str, Any]:
    return next(p for p in data["photos"] if p["id"] == pid)


def floor_markers_seen_once(data: dict[str, Any], placement: Placement | None,
                             floor: set[str]) -> dict[str, tuple[str, np.ndarray]]:
    """Floor markers that exactly one jointly placed photo shows (and the joint did not place):
    name → (that photo, its click)."""
    if placement is None:
        return {}
    seen: dict[str, list[tuple[str, np.ndarray]]] = {}
    for pid in placement.cameras:
        for n, uv in decode.sightings(photo_of(data, pid)).items():
            if n in floor and n not in placement.markers:
                seen.setdefault(n, []).append((pid, uv))
    return {n: v[0] for n, v in seen.items() if len(v) == 1}


def results_record(data: dict[str, Any], photos: dict[str, PhotoCalibration], placement: Placement | None,
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
            tested = cal.second_term_test is not None
            distortion = distortion_record(
                cam.K, cal.width, cal.height, cam.k1, cam.k1_sigma, cal.k1_source, k2=cal.k2,
                k2_sigma=cal.k2_sigma, k2_source=cal.k2_source if tested else None,
                corner_sigma=cal.distortion_corner_px_sigma if cal.k2_sigma > 0.0 else None,
                k1_correlation=(float(cal.covariance_lens[6, 7] / (cal.k1_sigma * cal.k2_sigma))
                                if cal.k1_sigma > 0.0 and cal.k2_sigma > 0.0 else None))
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
                                "height above the floor is taken as 1 and every position is in that unit; to measure "
                                "in metres give one length known at the scene: in the modelling screen press K, "
                                "drag along an edge whose length you know (a door's height, foot first) and type "
                                "it in the Scale tab, or enter the camera's height there (in the file: "
                                f"$.known_lengths, or $.photos[{ids.index(pid)}].camera_height)")
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
    for n, (pid, uv) in sorted(floor_markers_seen_once(data, placement, floor).items()):
        pc = placement.cameras[pid] if placement else None
        if pc is not None and n not in all_markers:
            # One photo of the joint placement shows it: placed from that photo alone, on the floor.
            try:
                all_markers[n] = floor_point(pid, pc.K, pc.R, pc.C, pc.covariance, uv, k1=pc.k1, k2=pc.k2,
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
        "origin": origin_text(placement, alone),
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


def origin_text(placement: Placement | None, alone: dict[str, SinglePhotoPlacement]) -> str:
    """What the world's origin is: the joint placement's origin marker, or each photo placed alone's
    origin (once, where they all share it)."""
    if placement is not None:
        return f"marker '{placement.origin}'"
    if not alone:
        return "none: no photo is placed"
    texts = {a.origin.describe() for a in alone.values()}
    if len(texts) == 1:
        return texts.pop()
    return "; ".join(f"photo '{pid}': {a.origin.describe()}" for pid, a in alone.items())
