"""Register further photos to the model (paper §3.2): ``vebuild register PROJECT [PHOTO ...]``.

A photo that could not be calibrated with the others (no origin marker, no shared markers, or no
vanishing segments at all) is placed from the points whose positions are now known: calibrated
markers and the solved model's vertices (``model_solution``). The camera is written into
``calibration.cameras`` like any other, its mode saying how it was found.

A focal length the user gave for the photo (its ``focal_px``) is always used, as in
``vebuild calibrate``, ahead of EXIF's; a principal point the user gave (``principal_point``) is
the centre and 1σ of the principal point's prior, in both ways of registering.

A photo's lens distortion is used where it is known, held at its k1: the vanishing-point
calibration's, or, for a photo placed from points alone, the ``distortion`` of the camera record
it already has (re-registering it). The record written carries that ``distortion`` (FORMAT.md);
a photo with none is registered as a pinhole.

The known points are not exact: the calibrated markers carry their 1σ (``calibration.markers``),
the solved model's vertices the joint covariance of the solve (``model_solution.covariance``,
carried to the vertices and to the markers the solve re-calibrated by
:func:`vebuild.analysis.measure.propagate`). That joint covariance goes into the camera's
covariance beside the clicks' (:mod:`vebuild.calibration.register`). The record keeps, as
``registration_prior``, what held the camera before any point (FORMAT.md); a re-calibrating solve
holds the photo by that prior alone (:func:`recalibration_cameras`), since the photo's pins and
sightings, and the model points they rest on, are in the re-calibration themselves: counted once.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild.analysis.measure import propagate
from vebuild.analysis.solved import Point, SolvedModel
from vebuild.calibration.photo import calibrate_photo
from vebuild.calibration.priors import DistortionPrior
from vebuild.calibration.register import Registered, register_from_points, register_with_vanishing_points
from vebuild.camera import ImageCamera, Lens
from vebuild.errors import CalibrationError, VebuildError
from vebuild.project import Project, decode, provenance
from vebuild.project.decode import known_points
from vebuild.project.records import camera_record, distortion_record, json_values

from .calibrate import exif_focal_prior

#: A marker whose calibration 1σ (any axis, metres) is not below this is not a known point: its
#: position is undetermined (FORMAT.md writes the largest float there).
UNKNOWN_MARKER_SIGMA_M = 1e3
#: The variance (pixels², radians², metres²) that stands for "free" in a re-calibration's prior of
#: a registered photo (:func:`recalibration_cameras`): a 1σ of 1000 px, rad or m weighs nothing
#: beside one click.
FREE_PRIOR_VARIANCE = 1e6


def register_photos(project: Project, photo_ids: list[str] | None = None) -> dict[str, Registered]:
    data = project.data
    cal = data.get("calibration")
    if not cal:
        raise VebuildError(f"{project.path}: nothing to register to: run `vebuild calibrate` "
                           "(and `vebuild solve`) first")
    ids = [p["id"] for p in data["photos"]]
    targets = photo_ids or [pid for pid in ids if pid not in cal["cameras"]]
    pts = known_points(data)
    sig = decode.marker_sigmas(data)
    pts = {n: X for n, X in pts.items() if n not in sig or bool(np.all(sig[n] < UNKNOWN_MARKER_SIGMA_M))}
    solved = SolvedModel.from_project(project) if data.get("model_solution") else None
    if solved is not None:  # the markers where the solution holds them, as its vertices: one solution's points
        pts.update({n: solved.marker_position(n).copy() for n in pts if ":" not in n and n in solved.marker_col})
    settings = project.settings
    out = {}
    for pid in targets:
        if pid not in ids:
            raise VebuildError(f"{project.path}: no photo with id '{pid}' (the photos are: {', '.join(ids)})")
        photo = next(p for p in data["photos"] if p["id"] == pid)
        obs = {n: uv for n, uv in (photo.get("marker_observations") or {}).items() if n in pts}
        for pin in (data.get("model") or {}).get("pins", []):
            name = f"{pin['node']}:{pin['handle']}"
            if pin["photo"] == pid and pin.get("fixed", True) and name in pts:
                obs[name] = pin["uv"]
        names = sorted(obs)
        X = np.array([pts[n] for n in names]).reshape(-1, 3)
        uv = np.array([obs[n] for n in names], float).reshape(-1, 2)
        S = points_covariance(names, solved, sig)
        marks = decode.photo_marks(photo)
        segs = marks.segments
        exif = exif_focal_prior(photo, settings["exif_focal_sigma_rel"])
        try:
            if len(segs) >= 2:
                vp = calibrate_photo(segs, photo["width"], photo["height"], photo=pid,
                                     click_sigma_px=settings["click_sigma_px"],
                                     principal_point=marks.principal_point,
                                     principal_point_sigma_rel=settings["principal_point_sigma_rel"],
                                     focal=marks.focal, exif_focal=exif)
                reg = register_with_vanishing_points(vp, X, uv, click_sigma_px=settings["click_sigma_px"],
                                                     point_covariance=S)
                reason = f"{vp.mode} vanishing-point calibration, placed from {len(X)} known points"
            else:
                reg = register_from_points(X, uv, photo["width"], photo["height"], photo=pid,
                                           click_sigma_px=settings["click_sigma_px"],
                                           principal_point_sigma_rel=settings["principal_point_sigma_rel"],
                                           focal=marks.focal or exif, principal_point=marks.principal_point,
                                           distortion=_known_distortion(cal, pid), point_covariance=S)
                reason = f"no usable vanishing points: the whole camera from {len(X)} known points"
                given = [w for w, g in (("focal length", marks.focal), ("principal point", marks.principal_point))
                         if g is not None]
                if given:
                    reason += f", with the {' and '.join(given)} the user gave"
                elif exif is not None:
                    reason += ", with the EXIF focal length"
        except CalibrationError as e:
            raise VebuildError(f"{project.path}: $.photos[{ids.index(pid)}] {e}") from None
        if reg.k1_source:
            reason += f", through its lens distortion (k1 {reg.k1:+.4f}, {reg.k1_source})"
        cal["cameras"][pid] = _record(reg, names, reason, photo["width"], photo["height"])
        out[pid] = reg
    provenance.stamp(data, "calibration", photos=list(out))  # these photos' inputs (vebuild.project.provenance)
    return out


def points_covariance(names: list[str], solved: SolvedModel | None, sigmas: dict[str, Any]) -> np.ndarray:
    """The (3n, 3n) joint covariance of the known points ``names`` (``node:handle`` or a marker):
    through the solved model's covariance where the project is solved (its vertices, and the
    markers it holds, with their correlations), else the markers' calibration 1σ per axis."""
    n = len(names)
    if solved is None:
        return np.diag(np.concatenate([np.asarray(sigmas.get(m, np.zeros(3)), float) ** 2 for m in names]
                                      or [np.zeros(0)]))
    points = []
    for name in names:
        if ":" in name:
            node, handle = name.split(":", 1)
            points.append(Point(name, "handle", node=node, handle=handle))
        else:
            points.append(Point(name, "marker", marker=name))
    exact = [k for k, p in enumerate(points) if p.kind == "marker" and p.marker not in solved.marker_col]
    tied = [p for p in points if not (p.kind == "marker" and p.marker not in solved.marker_col)]
    out = np.zeros((3 * n, 3 * n))
    if tied:
        def world(x: np.ndarray) -> np.ndarray:
            state = solved._state(x)  # the model's transforms once for all the points
            return np.concatenate([solved.world(p, x, state) for p in tied])

        est = propagate(solved, world)
        rows = np.concatenate([np.arange(3 * k, 3 * k + 3) for k, p in enumerate(points) if p in tied])
        out[np.ix_(rows, rows)] = est.cov
    for k in exact:  # a marker the solution does not hold: its calibration 1σ
        out[3 * k: 3 * k + 3, 3 * k: 3 * k + 3] = np.diag(np.asarray(sigmas.get(names[k], np.zeros(3)), float) ** 2)
    return out


def recalibration_cameras(project: Project, cameras: dict[str, ImageCamera], refine_intrinsics: bool
                          ) -> dict[str, ImageCamera]:
    """The priors of a re-calibration: each photo held by what held its camera before any point,
    not by its calibration, whose covariance already counts the marker sightings, pins and scale
    distances that the re-calibration uses again (counted twice they would make every interval too
    narrow). A registered photo (``calibration.cameras[id].mode`` "registered") is held by its
    ``registration_prior``, a jointly placed photo by its ``vanishing_point_prior`` (its
    vanishing-point K, R and k1, and its own camera height; FORMAT.md); a photo placed alone keeps
    its calibration. Free entries of the prior get FREE_PRIOR_VARIANCE. Without
    ``refine_intrinsics`` the calibrated K is held (as every photo's is) and its covariance kept
    for the record."""
    out = dict(cameras)
    for pid, rec in (project.data.get("calibration") or {}).get("cameras", {}).items():
        prior = rec.get("registration_prior") if rec.get("mode") == "registered" else rec.get("vanishing_point_prior")
        if not prior or pid not in cameras:
            continue
        cam = cameras[pid]
        P = np.array([[np.nan if v is None else v for v in row] for row in prior["covariance"]], float)
        free = np.isnan(np.diag(P))
        P[free, :], P[:, free] = 0.0, 0.0
        P[free, free] = FREE_PRIOR_VARIANCE
        K = np.asarray(prior["K"], float)
        if not refine_intrinsics and cam.covariance is not None:
            K = cam.K
            P[:3, :] = P[:, :3] = 0.0
            P[:3, :3] = np.asarray(cam.covariance, float)[:3, :3]
        k1 = float(prior["k1"]["value"]) if "k1" in prior else cam.lens.k1
        out[pid] = ImageCamera(pid, K, np.asarray(prior["R"], float), cam.C, cam.width, cam.height,
                               covariance=P, lens=Lens(k1, cam.lens.k2))
    return out


def recalibration_k1_sigmas(project: Project, sigmas: dict[str, float]) -> dict[str, float]:
    """``sigmas`` (photo id → k1's 1σ, from the calibration records) with the 1σ of each
    ``vanishing_point_prior`` that has a k1 in its place: a re-calibration holds that photo's k1 by
    what the vanishing points alone said of it (:func:`recalibration_cameras`)."""
    out = dict(sigmas)
    for pid, rec in (project.data.get("calibration") or {}).get("cameras", {}).items():
        prior = rec.get("vanishing_point_prior") if rec.get("mode") != "registered" else None
        if prior and "k1" in prior and pid in out:
            out[pid] = float(prior["k1"]["sigma"])
    return out


def _known_distortion(cal: dict[str, Any], pid: str) -> DistortionPrior | None:
    """The lens distortion of the photo's present camera record (FORMAT.md ``distortion``), if any."""
    d = (cal["cameras"].get(pid) or {}).get("distortion")
    if not d:
        return None
    sigma = d["k1"].get("sigma")
    source = d.get("source") or "its earlier calibration"
    return DistortionPrior(float(d["k1"]["value"]), 0.0 if sigma is None else float(sigma), source)


def _record(reg: Registered, names: list[str], reason: str, width: int, height: int) -> dict[str, Any]:
    distortion = distortion_record(reg.K, width, height, reg.k1, reg.k1_sigma, reg.k1_source, k2=reg.k2) \
        if reg.k1_source else None
    return {
        "mode": "registered",
        "mode_reason": reason,
        "focal_source": reg.method,
        **camera_record(reg.K, reg.R, reg.C, reg.covariance, distortion),
        "registration_prior": {"K": json_values(reg.K if reg.prior_K is None else reg.prior_K),
                               "R": json_values(reg.R if reg.prior_R is None else reg.prior_R),
                               "covariance": json_values(reg.prior_covariance)},
        "vanishing_points": {},
        "marker_residuals_px": {n: json_values(r) for n, r in zip(names, reg.residuals_px, strict=True)
                                if ":" not in n},
        "rms_px": float(np.sqrt(np.mean(reg.residuals_px**2))),
    }
