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
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..calibration.photo import calibrate_photo
from ..calibration.priors import DistortionPrior
from ..calibration.register import Registered, register_from_points, register_with_vanishing_points
from ..errors import CalibrationError, VebuildError
from ..project import Project, decode, provenance
from ..project.decode import known_points
from ..project.records import camera_record, distortion_record, json_values
from .calibrate import exif_focal_prior


def register_photos(project: Project, photo_ids: list[str] | None = None) -> dict[str, Registered]:
    data = project.data
    cal = data.get("calibration")
    if not cal:
        raise VebuildError(f"{project.path}: nothing to register to: run `vebuild calibrate` "
                           "(and `vebuild solve`) first")
    ids = [p["id"] for p in data["photos"]]
    targets = photo_ids or [pid for pid in ids if pid not in cal["cameras"]]
    pts = known_points(data)
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
                reg = register_with_vanishing_points(vp, X, uv, click_sigma_px=settings["click_sigma_px"])
                reason = f"{vp.mode} vanishing-point calibration, placed from {len(X)} known points"
            else:
                reg = register_from_points(X, uv, photo["width"], photo["height"], photo=pid,
                                           click_sigma_px=settings["click_sigma_px"],
                                           principal_point_sigma_rel=settings["principal_point_sigma_rel"],
                                           focal=marks.focal or exif, principal_point=marks.principal_point,
                                           distortion=_known_distortion(cal, pid))
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


def _known_distortion(cal: dict[str, Any], pid: str) -> DistortionPrior | None:
    """The lens distortion of the photo's present camera record (FORMAT.md ``distortion``), if any."""
    d = (cal["cameras"].get(pid) or {}).get("distortion")
    if not d:
        return None
    sigma = d["k1"].get("sigma")
    source = d.get("source") or "its earlier calibration"
    return DistortionPrior(float(d["k1"]["value"]), 0.0 if sigma is None else float(sigma), source)


def _record(reg: Registered, names: list[str], reason: str, width: int, height: int) -> dict[str, Any]:
    distortion = distortion_record(reg.K, width, height, reg.k1, reg.k1_sigma, reg.k1_source) \
        if reg.k1_source else None
    return {
        "mode": "registered",
        "mode_reason": reason,
        "focal_source": reg.method,
        **camera_record(reg.K, reg.R, reg.C, reg.covariance, distortion),
        "vanishing_points": {},
        "marker_residuals_px": {n: json_values(r) for n, r in zip(names, reg.residuals_px, strict=True)
                                if ":" not in n},
        "rms_px": float(np.sqrt(np.mean(reg.residuals_px**2))),
    }
