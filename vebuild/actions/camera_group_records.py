"""The records of the calibration's camera groups (scenes/FORMAT.md ``calibration.camera_groups``).

A group's shared intrinsics are written once, under the group; each of its photos' camera records
names its group (``camera_group``) and carries the same K as every other photo of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from vebuild.calibration.camera_groups import CameraGroup
from vebuild.calibration.positions import CameraGroupPrior
from vebuild.calibration.shared_camera import GroupMember, SharedCalibration, calibrate_shared
from vebuild.project.records import json_values, value_sigma


@dataclass(frozen=True)
class GroupResult:
    """A camera group and its shared calibration (None: fewer than two of its photos could share
    intrinsics, so each was calibrated alone)."""

    group: CameraGroup
    shared: SharedCalibration | None


def calibrate_group(g: CameraGroup, members: list[GroupMember]) -> GroupResult:
    """One camera group calibrated together, its EXIF focal length once (where the user grouped
    photos whose EXIF differs, none)."""
    priors = [m.kwargs["exif_focal"] for m in members]
    exif = priors[0] if all(p is not None and p == priors[0] for p in priors) else None
    return GroupResult(g, calibrate_shared(g.id, members, exif_focal=exif))


def group_priors(groups: dict[str, GroupResult]) -> list[CameraGroupPrior]:
    """What placement holds each shared group's photos by: one set of intrinsics, their joint prior."""
    return [CameraGroupPrior(tuple(r.shared.photos), r.shared.joint_covariance) for r in groups.values()
            if r.shared is not None]


def no_serial_note(g: CameraGroup) -> str | None:
    """What grouping by EXIF without a body serial risks, for an EXIF group whose photos record none."""
    if g.source != "exif" or g.serial:
        return None
    return ("EXIF records no body serial: photos of two bodies of this model at this focal length would be merged "
            "(release a photo with own_camera, or group photos yourself in camera_groups)")


def group_records(groups: dict[str, GroupResult], exif_check_record: Any) -> tuple[list[dict[str, Any]], list[str]]:
    """The records of ``calibration.camera_groups`` and the warnings they bring (a photo released
    from its group, a group that could not share)."""
    records, warnings = [], []
    for gid, res in groups.items():
        g, s = res.group, res.shared
        rec: dict[str, Any] = {"id": gid, "source": g.source, "photos": list(g.photos)}
        if g.source == "exif":
            rec["camera"] = g.camera
            rec["body_serial"] = g.serial
        note = no_serial_note(g)
        if note:
            rec["note"] = note
        if s is None:
            rec["shared"] = False
            warnings.append(f"camera group '{gid}': fewer than two of its photos can share intrinsics, so each of "
                            "its photos is calibrated on its own")
            records.append(rec)
            continue
        rec.update({
            "shared": True,
            "calibrated": list(s.photos),
            "mode": s.mode,
            "mode_reason": s.reason,
            "focal_source": s.focal_source,
            "focal_px": value_sigma(s.f, s.f_sigma),
            "principal_point": value_sigma(s.principal_point, s.principal_point_sigma),
            "distortion": {"k1": float(s.k1), "sigma": float(s.k1_sigma), "source": s.k1_source},
            "covariance": json_values(s.covariance),
            "variance_factor": float(s.variance_factor),
            "released": dict(s.released),
        })
        if s.exif_check is not None:
            rec["exif_focal_check"] = exif_check_record(s.exif_check)
        for pid, why in s.released.items():
            warnings.append(f"photo '{pid}' is released from camera group '{gid}': {why}")
        records.append(rec)
    return records, warnings


def add_group_records(result: dict[str, Any], groups: dict[str, GroupResult], exif_check_record: Any) -> None:
    """Write ``camera_groups`` into a calibration record, ``camera_group`` into each of the groups'
    photos' camera records (placed or not), and the groups' warnings."""
    if not groups:
        return
    records, warnings = group_records(groups, exif_check_record)
    result["camera_groups"] = records
    for rec in records:
        for pid in rec.get("calibrated", []):
            for where in ("cameras", "unplaced"):
                if pid in result.get(where, {}):
                    result[where][pid]["camera_group"] = rec["id"]
    result["warnings"] += warnings


def apply_group_options(data: dict[str, Any], file: Any, group: list[str], release: list[str]) -> None:
    """``vebuild calibrate --group ID=P1,P2[,…] --release PHOTO``: the user's camera groups and
    releases, written into the document (saved with the calibration, checked as the file is).

    A photo put in a group leaves any other group and is no longer released; a released photo
    leaves the user's groups (a group left with one photo is dropped) and gets ``own_camera``.
    """
    from vebuild.errors import VebuildError
    from vebuild.project.json_paths import listing
    from vebuild.project.validation import validate

    ids = [p["id"] for p in data["photos"]]
    groups = [dict(g) for g in data.get("camera_groups") or []]
    for text in group:
        gid, sep, rest = text.partition("=")
        members = [p.strip() for p in rest.split(",") if p.strip()]
        if not sep or not gid.strip() or len(members) < 2:
            raise VebuildError(f"--group {text!r}: expected ID=PHOTO,PHOTO[,...]: a group's name, '=' and two photo "
                               "ids or more, separated by commas")
        for pid in members:
            if pid not in ids:
                raise VebuildError(f"--group {text!r}: names the photo {pid!r}, but {file} has no photo of that id; "
                                   f"expected one of: {listing(ids)}")
        groups = [{**g, "photos": [p for p in g["photos"] if p not in members]} for g in groups if g["id"] != gid]
        groups.append({"id": gid.strip(), "photos": members})
        for p in data["photos"]:
            if p["id"] in members:
                p.pop("own_camera", None)
    for pid in release:
        if pid not in ids:
            raise VebuildError(f"--release {pid!r}: expected a photo id of {file} (one of: {listing(ids)})")
        groups = [{**g, "photos": [p for p in g["photos"] if p != pid]} for g in groups]
        data["photos"][ids.index(pid)]["own_camera"] = True
    groups = [g for g in groups if len(g["photos"]) >= 2]
    if groups:
        data["camera_groups"] = groups
    else:
        data.pop("camera_groups", None)
    validate(data, file)


def solved_group_records(problem: Any, solution: Any) -> list[dict[str, Any]]:
    """``model_solution.camera_groups``: each re-calibrated camera group's one focal length,
    principal point and k1 with their 1σ (the solve's covariance over the group's block)."""
    out = []
    for gid, blk in problem.layout.groups.items():
        photos = list(problem.options.camera_groups[gid].photos)
        cam = solution.cameras[photos[0]]
        sig = np.sqrt(np.maximum(np.diag(solution.covariance[blk.slice, blk.slice]), 0.0))
        rec: dict[str, Any] = {"id": gid, "photos": photos,
                               "focal_px": value_sigma(float(cam.K[0, 0]), float(sig[0])),
                               "principal_point": value_sigma(cam.K[:2, 2], sig[1:3]),
                               "distortion": {"k1": float(cam.lens.k1),
                                              "sigma": float(sig[3]) if len(sig) > 3 else None,
                                              "refined": len(sig) > 3}}
        out.append(rec)
    return out
