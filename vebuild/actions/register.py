"""Register further photos to the model (paper §3.2): ``vebuild register PROJECT [PHOTO ...]``.

A photo that could not be calibrated with the others (no origin marker, no shared markers, or no
vanishing segments at all) is placed from the points whose positions are now known: calibrated
markers and the solved model's vertices (``model_solution``). The camera is written into
``calibration.cameras`` like any other, its mode saying how it was found.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..calibration.photo import calibrate_photo
from ..calibration.register import Registered, register_from_points, register_with_vanishing_points
from ..errors import CalibrationError, VebuildError
from ..project import Project, decode
from ..project.decode import known_points
from ..project.records import camera_record, json_values
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
        segs = decode.photo_marks(photo).segments
        exif = exif_focal_prior(photo, settings["exif_focal_sigma_rel"])
        try:
            if len(segs) >= 2:
                vp = calibrate_photo(segs, photo["width"], photo["height"], photo=pid,
                                     click_sigma_px=settings["click_sigma_px"],
                                     principal_point_sigma_rel=settings["principal_point_sigma_rel"],
                                     exif_focal=exif)
                reg = register_with_vanishing_points(vp, X, uv, click_sigma_px=settings["click_sigma_px"])
                reason = f"{vp.mode} vanishing-point calibration, placed from {len(X)} known points"
            else:
                reg = register_from_points(X, uv, photo["width"], photo["height"], photo=pid,
                                           click_sigma_px=settings["click_sigma_px"],
                                           principal_point_sigma_rel=settings["principal_point_sigma_rel"],
                                           focal=exif)
                reason = f"no usable vanishing points: the whole camera from {len(X)} known points"
        except CalibrationError as e:
            raise VebuildError(f"{project.path}: $.photos[{ids.index(pid)}] {e}") from None
        cal["cameras"][pid] = _record(reg, names, reason)
        out[pid] = reg
    return out


def _record(reg: Registered, names: list[str], reason: str) -> dict[str, Any]:
    return {
        "mode": "registered",
        "mode_reason": reason,
        "focal_source": reg.method,
        **camera_record(reg.K, reg.R, reg.C, reg.covariance),
        "vanishing_points": {},
        "marker_residuals_px": {n: json_values(r) for n, r in zip(names, reg.residuals_px, strict=True)
                                if ":" not in n},
        "rms_px": float(np.sqrt(np.mean(reg.residuals_px**2))),
    }
