"""Photos whose world axes disagree with the others', left out of ``vebuild calibrate``.

Before placing: :func:`leave_out_unoriented` tests every calibrated rotation against the others
through the shared markers (:mod:`vebuild.calibration.orientation`). After placing:
:func:`misfit` finds a photo placed turned that the test could not tell (too few shared markers),
its markers far from where the others put them. Each is left out (``calibration.left_out``) with
the one action that fixes it (docs/detect.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild.calibration.axes_choice import MIN_SHARED_MARKERS
from vebuild.calibration.orientation import check_orientation, fix_words
from vebuild.calibration.photo import PhotoCalibration
from vebuild.calibration.positions import Placement
from vebuild.camera import undistort_pixels
from vebuild.constants import OUTLIER_SIGMAS
from vebuild.errors import CalibrationError
from vebuild.project import Project, decode


def _photo(data: dict[str, Any], pid: str) -> dict[str, Any]:
    return next(p for p in data["photos"] if p["id"] == pid)


def leave_out_unoriented(project: Project, photos: dict[str, PhotoCalibration],
                          left_out: dict[str, CalibrationError]) -> None:
    """Move the photos whose world axes disagree with the others' (or whose x axis ``detect``
    could not choose, and the markers cannot orient) from ``photos`` to ``left_out``, each with the
    one action that orients it (vebuild.calibration.orientation)."""
    data = project.data
    unresolved = {pid: str(_photo(data, pid)["x_axis_unresolved"]) for pid in photos
                  if _photo(data, pid).get("x_axis_unresolved")}
    rays: dict[str, dict[str, np.ndarray]] = {}
    for pid, cal in photos.items():
        obs = decode.sightings(_photo(data, pid))
        if obs:
            names = sorted(obs)
            uv = np.array([obs[n] for n in names])
            if cal.k1 != 0.0:
                uv = undistort_pixels(cal.K, uv, cal.lens)
            xy = (uv - cal.K[:2, 2]) / cal.K[0, 0]
            rays[pid] = {n: np.array([x, y, 1.0]) for n, (x, y) in zip(names, xy, strict=True)}
    found = check_orientation({pid: cal.R for pid, cal in photos.items()}, rays, unresolved,
                              data.get("origin_marker"))
    for pid, u in found.items():
        detected = pid in unresolved or any(s is not None for v in (_photo(data, pid).get("vanishing_segment_sigmas")
                                                                   or {}).values() for s in v or [])
        left_out[pid] = CalibrationError(pid, f"its world axes are not oriented consistently with the other "
                                         f"photos': {u.reason}; {fix_words(u, str(project.path), detected)}")
        del photos[pid]


def misfit(placement: Placement, obs_of: dict[str, dict[str, np.ndarray]]) -> tuple[str, str] | None:
    """The jointly placed photo whose markers most of all lie far from where the others put them
    (half of them or more, two at least, each beyond OUTLIER_SIGMAS): a photo placed with its axes
    turned, which the orientation test could not tell (too few shared markers); with its reason and
    the one action that lets the test tell it. None where no photo misses so."""
    worst: tuple[float, str, list[float]] | None = None
    for pid, cam in (placement.unwidened or placement).cameras.items():
        n = len([m for m in cam.marker_residuals_px if ":" not in m])
        away = [cam.outlier_offsets_px.get(m, 0.0) for m in cam.outliers if ":" not in m]
        if len(away) >= 2 and 2 * len(away) >= n and (worst is None or len(away) / n > worst[0]):
            worst = (len(away) / n, pid, away)
    if worst is None:
        return None
    _, pid, away = worst
    mine = {m for m in obs_of[pid] if ":" not in m}  # markers: what the orientation test compares
    shared = {q: len(mine & set(obs_of[q])) for q in placement.cameras if q != pid}
    q = max(shared, key=lambda q: (shared[q], q))
    return pid, (f"its markers lie {min(away):.0f}–{max(away):.0f} px from where the other photos put them "
                 f"({len(away)} of its {len(mine)}, each beyond {OUTLIER_SIGMAS:g}σ of the click noise): its camera "
                 "disagrees with theirs (its world axes turned about z, or its vanishing segments off), and it shares "
                 f"too few markers with any one photo to test its axes (at most {shared[q]} with '{q}', "
                 f"{MIN_SHARED_MARKERS} are needed); mark {max(MIN_SHARED_MARKERS - shared[q], 1)} more marker(s) "
                 f"that photo '{q}' also shows")
