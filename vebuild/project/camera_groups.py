"""The checks of the user's camera groups (scenes/FORMAT.md "Camera groups"), beyond the schema's,
and the calibration's camera groups decoded for a re-calibration (:func:`recalibration_groups`).

Each named photo exists, is in one group only, and is not released from groups (``own_camera``);
a group's photos have one size as displayed (one camera held one way: one principal point).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from vebuild.errors import ProjectError
from vebuild.model.camera_blocks import SharedIntrinsics

from .json_paths import listing


def check_camera_groups(data: dict[str, Any], file: Any) -> None:
    """Raise ProjectError naming the file, the field and what was expected."""
    photos = {p["id"]: (i, p) for i, p in enumerate(data["photos"])}
    first_group: dict[str, int] = {}
    ids: dict[str, int] = {}
    for i, g in enumerate(data.get("camera_groups") or []):
        where = f"$.camera_groups[{i}]"
        if g["id"] in ids:
            raise ProjectError(file, f"{where}.id", f"the camera group id {g['id']!r} is already used by "
                               f"$.camera_groups[{ids[g['id']]}]; each camera group id must be unique")
        ids[g["id"]] = i
        size = None
        for k, pid in enumerate(g["photos"]):
            here = f"{where}.photos[{k}]"
            if pid not in photos:
                raise ProjectError(file, here, f"names the photo {pid!r}, but $.photos has no photo of that id "
                                   f"(the photos are: {listing(list(photos))})")
            if pid in first_group:
                raise ProjectError(file, here, f"the photo {pid!r} is already in $.camera_groups[{first_group[pid]}]; "
                                   "expected each photo in one camera group at most (a photo was taken with one "
                                   "camera)")
            first_group[pid] = i
            j, photo = photos[pid]
            if photo.get("own_camera"):
                raise ProjectError(file, here, f"the photo {pid!r} is released from camera groups ($.photos[{j}]."
                                   "own_camera is true); expected it either in a group or released: remove it "
                                   "from the group, or its own_camera")
            wh = (photo["width"], photo["height"])
            if size is None:
                size = (pid, wh)
            elif wh != size[1]:
                raise ProjectError(file, here, f"the photo {pid!r} is {wh[0]}×{wh[1]} px, but {size[0]!r}, the "
                                   f"group's first, is {size[1][0]}×{size[1][1]} px; expected the photos of one "
                                   "camera group to have one size as displayed (one camera, held one way: a "
                                   "photo turned a quarter or cropped has another principal point), so put it "
                                   "in a group of its own")


def recalibration_groups(data: dict[str, Any], cameras: Mapping[str, Any], file: Any) -> dict[str, SharedIntrinsics]:
    """The camera groups of a re-calibration (``vebuild solve --recalibrate``): each shared group
    of ``calibration.camera_groups`` with two or more of its calibrated photos among ``cameras``
    (a registered photo keeps its own), its shared K and k1 and its joint prior over (f, cx, cy,
    k1) from the vanishing points (the record's ``covariance``); k1 refined where its 1σ is > 0.
    A released photo is in no group: it keeps its own intrinsics. A record not as `vebuild
    calibrate` writes it is refused with a ProjectError naming it."""
    cal = data.get("calibration") or {}
    out = {}
    for i, rec in enumerate(cal.get("camera_groups") or []):
        if not isinstance(rec, dict) or not rec.get("shared"):
            continue
        try:
            photos = tuple(p for p in rec["calibrated"] if p in cameras
                           and (cal["cameras"].get(p) or {}).get("mode") != "registered")
            cov = np.array([[np.nan if v is None else v for v in row] for row in rec["covariance"]], float)
            f, (cx, cy) = float(rec["focal_px"]["value"]), map(float, rec["principal_point"]["value"])
            k1, k1_sigma = float(rec["distortion"]["k1"]), rec["distortion"]["sigma"]
            k1_sigma = float("nan") if k1_sigma is None else float(k1_sigma)
            if cov.shape != (4, 4) or not np.all(np.isfinite([f, cx, cy, k1])) or f <= 0:
                raise ValueError
        except (KeyError, TypeError, ValueError, AttributeError):
            raise ProjectError(file, f"$.calibration.camera_groups[{i}]", "expected a camera group's record as "
                               "`vebuild calibrate` writes it (calibrated, focal_px, principal_point, distortion, "
                               "and a 4×4 covariance); run `vebuild calibrate` again") from None
        if len(photos) < 2 or not np.all(np.isfinite(cov[:3, :3])):
            continue  # no two photos to share, or the group's intrinsics undetermined: each its own
        refine_k1 = bool(np.isfinite(k1_sigma) and k1_sigma > 0 and np.isfinite(cov[3, 3]) and cov[3, 3] > 0)
        K = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
        out[str(rec["id"])] = SharedIntrinsics(photos, K, k1, np.nan_to_num(cov), refine_k1)
    return out
