"""Stills of one fixed camera calibrate as one photo (scenes/FORMAT.md "Stills from video").

Frames of one video stream (same video SHA-256, same stream, same size) were taken by one camera that
did not move: one K, one R, one C. The calibration takes them as one photo whose marks are the union
of theirs (vanishing segments of every frame, marker observations of every frame: the mean where a
marker is marked on several frames, since a still point is at one pixel in all of them; pins, known
lengths and every other mark naming a frame name the first), so that lines and markers marked on
different frames add up exactly as if all were marked on one. The camera found is written to each
frame, with ``fixed_camera`` naming the frames it was found from.

A camera that pans or zooms is not fixed: give its frames ``own_camera`` (or put them in camera
groups of their own) and each is calibrated alone.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from vebuild.project.stills import fixed_camera_key

_AXES = ("x", "y", "z")


def fixed_sets(data: dict[str, Any]) -> list[list[str]]:
    """The photo ids of each fixed camera with two or more stills (in project order)."""
    by_key: dict[tuple[Any, ...], list[str]] = {}
    for p in data["photos"]:
        key = fixed_camera_key(p)
        if key is not None and not p.get("own_camera"):
            by_key.setdefault((*key, p["width"], p["height"]), []).append(p["id"])
    return [ids for ids in by_key.values() if len(ids) >= 2]


def _merge_photo(photos: list[dict[str, Any]]) -> dict[str, Any]:
    first = copy.deepcopy(photos[0])
    segments: dict[str, list[Any]] = {}
    sigmas: dict[str, list[Any]] = {}
    any_sigma = {a for p in photos for a in (p.get("vanishing_segment_sigmas") or {})}
    for p in photos:
        for a in _AXES:
            rows = (p.get("vanishing_segments") or {}).get(a) or []
            segments.setdefault(a, []).extend(copy.deepcopy(rows))
            if a in any_sigma:
                given = (p.get("vanishing_segment_sigmas") or {}).get(a)
                sigmas.setdefault(a, []).extend(given if given is not None else [None] * len(rows))
    first["vanishing_segments"] = {a: rows for a, rows in segments.items() if rows}
    if sigmas:
        first["vanishing_segment_sigmas"] = {a: s for a, s in sigmas.items() if segments.get(a)}
    else:
        first.pop("vanishing_segment_sigmas", None)
    seen: dict[str, list[Any]] = {}
    for p in photos:
        for name, uv in (p.get("marker_observations") or {}).items():
            seen.setdefault(name, []).append(uv)
    first["marker_observations"] = {n: [float(v) for v in np.mean(np.asarray(uvs, float), axis=0)]
                                    for n, uvs in seen.items()}
    if any(p.get("x_axis_unresolved") for p in photos):
        # One frame's axes unresolved: the union's are too (resolved from the markers, or left out).
        first["x_axis_unresolved"] = next(p["x_axis_unresolved"] for p in photos if p.get("x_axis_unresolved"))
    for key in ("focal_px", "principal_point", "camera_height"):
        if key not in first:
            given = next((p[key] for p in photos if key in p), None)
            if given is not None:
                first[key] = copy.deepcopy(given)
    return first


def _renamed(value: Any, to: dict[str, str]) -> Any:
    """``value`` with every ``"photo": ID`` of a merged frame naming its set's first."""
    if isinstance(value, dict):
        return {k: (to.get(v, v) if k == "photo" and isinstance(v, str) else _renamed(v, to)) for k, v in value.items()}
    if isinstance(value, list):
        return [_renamed(v, to) for v in value]
    return value


def merged(data: dict[str, Any]) -> tuple[dict[str, Any], list[list[str]]]:
    """The document the calibration runs on (each fixed camera's stills as one photo, its first) and
    the fixed sets; the document itself where there are none."""
    sets = fixed_sets(data)
    if not sets:
        return data, []
    by_id = {p["id"]: p for p in data["photos"]}
    to = {pid: ids[0] for ids in sets for pid in ids[1:]}
    out = {k: (_renamed(v, to) if k not in ("photos", "calibration", "camera_groups", "audit") else v)
           for k, v in data.items()}
    firsts = {ids[0]: _merge_photo([by_id[i] for i in ids]) for ids in sets}
    out["photos"] = [firsts.get(p["id"], p) for p in data["photos"] if p["id"] not in to]
    groups = []
    for g in data.get("camera_groups") or []:
        kept = list(dict.fromkeys(to.get(pid, pid) for pid in g["photos"]))
        if len(kept) >= 2:
            groups.append({**g, "photos": kept})
    if groups:
        out["camera_groups"] = groups
    else:
        out.pop("camera_groups", None)
    return out, sets


def spread(result: dict[str, Any], sets: list[list[str]]) -> None:
    """Write each fixed camera's record (found for its first still) to every still of it."""
    cameras = result.get("cameras") or {}
    for ids in sets:
        first = ids[0]
        if first in cameras:
            cameras[first]["fixed_camera"] = {"stills": list(ids)}
            for pid in ids[1:]:
                cameras[pid] = copy.deepcopy(cameras[first])
        left = (result.get("left_out") or {}).get(first)
        if left is not None:
            for pid in ids[1:]:
                result["left_out"][pid] = copy.deepcopy(left)
    if cameras:
        order = list(cameras)
        result["cameras"] = {pid: cameras[pid] for pid in order}


def recalibration_warnings(data: dict[str, Any]) -> list[str]:
    """What a re-calibrating solve says of the stills of a fixed camera: it refines each still's
    camera on its own, each held by the prior of the one camera calibrated from all their marks, so
    that prior counts once per still and the re-calibrated σ can be optimistic (up to √n for n stills)."""
    return [f"stills {', '.join(repr(p) for p in ids)} are one fixed camera, but the re-calibration refines each "
            f"still's camera on its own, each held by that camera's calibration (counted {len(ids)} times): the "
            f"re-calibrated uncertainties of what they show may be too small, by up to √{len(ids)}; a solve without "
            "--recalibrate keeps the fixed camera's calibration" for ids in fixed_sets(data)]
