"""``vebuild bench detect``'s street photos with clutter (:mod:`vebuild.bench.clutter_photos`).

Each photo is detected (with its EXIF), every proposal accepted, and the photo calibrated as
``vebuild calibrate`` does it (:func:`vebuild.calibration.photo.calibrate_photo`, EXIF's focal
length told its real 4 %). Figures, prefixed ``clutter_``: ``focal_coverage_95`` and
``principal_point_coverage_95`` the share of calibrated photos whose true focal length (true
principal point: χ² with 2 degrees of freedom) lies inside its 95 % interval;
``focal_rel_error_median``/``_max``; ``photos_with_clutter_in_an_axis`` the photos with a proposed
segment more than 3 px from the line through its midpoint and every true vanishing point (the
true lens undone); ``not_calibrated`` those with fewer than two axes or a refused calibration.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild.actions.detect import propose
from vebuild.calibration.lines import _distances
from vebuild.calibration.photo import calibrate_photo
from vebuild.calibration.priors import FocalPrior
from vebuild.camera import Lens, undistort_pixels
from vebuild.errors import VebuildError

from .clutter_photos import clutter_photo, load, photo_record

#: Photos of the set, and with ``--quick``.
N_CLUTTER, N_CLUTTER_QUICK = 40, 10
#: A proposed segment this far (px) from every true vanishing point's line is clutter.
OFF_LINE_PX = 3.0


def clutter_row(i: int) -> dict[str, Any]:
    gp = clutter_photo(i)
    t = gp.truth
    K, R = np.array(t["K"]), np.array(t["R"])
    props = propose(load(gp), photo_record(gp, f"c{i:03d}"))
    row: dict[str, Any] = {"photo": f"c{i:03d}", "kind": t["kind"], "clutter": t["clutter"], "message": props.message,
                           "clutter_in_axes": 0, "covered": None, "pp_covered": None, "focal_err": None}
    segs: dict[str, list] = {}
    sig: dict[str, list] = {}
    for p in props.segments:
        segs.setdefault(p.axis, []).append(np.array(p.points))
        sig.setdefault(p.axis, []).append(p.sigma_px)
    if props.segments:
        ends = np.array([np.r_[p.points[:2], p.points[-2:]] for p in props.segments])
        u = undistort_pixels(K, ends.reshape(-1, 2), Lens(float(t["k1"]))).reshape(-1, 4)
        row["clutter_in_axes"] = int(np.sum(_distances(u, K @ R).min(axis=1) > OFF_LINE_PX))
    if len(segs) < 2:
        return row
    prior = FocalPrior(t["exif_focal_px"], t["exif_focal_sigma_rel"] * t["exif_focal_px"], "exif")
    try:
        cal = calibrate_photo(segs, t["width"], t["height"], photo=row["photo"], segment_sigma_px=sig,
                              exif_focal=prior)
    except VebuildError as e:
        row["refused"] = str(e)
        return row
    f, s = cal.K[0, 0], float(np.sqrt(cal.covariance[0, 0]))
    d = cal.K[:2, 2] - K[:2, 2]
    row.update(mode=cal.mode, focal_err=float(f / K[0, 0] - 1.0), covered=bool(abs(f - K[0, 0]) <= 1.96 * s),
               pp_covered=bool(d @ np.linalg.solve(cal.covariance[1:3, 1:3], d) <= 5.991))
    return row


def clutter_figures(n: int) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    rows = [clutter_row(i) for i in range(n)]
    done = [r for r in rows if r["covered"] is not None]
    fe = np.abs([r["focal_err"] for r in done])
    return {
        "clutter_photos": n,
        "clutter_focal_coverage_95": float(np.mean([r["covered"] for r in done])) if done else None,
        "clutter_principal_point_coverage_95": float(np.mean([r["pp_covered"] for r in done])) if done else None,
        "clutter_focal_rel_error_median": float(np.median(fe)) if done else None,
        "clutter_focal_rel_error_max": float(np.max(fe)) if done else None,
        "clutter_photos_with_clutter_in_an_axis": int(sum(r["clutter_in_axes"] > 0 for r in rows)),
        "clutter_not_calibrated": n - len(done),
    }, rows
