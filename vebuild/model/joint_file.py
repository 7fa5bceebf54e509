"""A joint from its project-file form (scenes/FORMAT.md, "Joints"): degrees in the file, radians
in :mod:`.joints`; each bad field a ModelError with its JSON path. The joints tied to a room's
openings are read by :mod:`.room_joints`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .joints import (
    JOINT_TYPES,
    FlushJoint,
    FreeJoint,
    HingeJoint,
    Joint,
    MarkerJoint,
    RestsOnJoint,
    SliderJoint,
    error_at,
    pose_matrix,
)
from .room_joints import jamb_of, room_joint_from_dict

Array = NDArray[np.float64]


def _solve_axis_flag(d: Mapping[str, Any], where: str, path: str | None) -> bool:
    value = d.get("solve_axis", False)
    if not isinstance(value, bool):
        raise error_at(where, None if path is None else f"{path}.solve_axis",
                       f"solve_axis must be true or false (whether the photos solve the {d.get('type')} joint's "
                       f"axis), got {value!r}")
    return value


def joint_from_dict(d: Mapping[str, Any], where: str, markers: Mapping[str, Array] | None = None,
                    path: str | None = None) -> Joint:
    """A joint from its project-file form (degrees); ModelError names ``where`` (and has the JSON
    path ``path``) on bad input."""
    kind = d.get("type")
    base = pose_matrix(d.get("translation", [0, 0, 0]), d.get("rotation_deg", [0, 0, 0]))

    def at(key: str) -> str | None:
        return None if path is None else f"{path}.{key}"

    def axis_of(default: list[float]) -> Array:
        axis = np.asarray(d.get("axis", default), float)
        if not np.hypot.reduce(np.abs(axis)) >= 1e-6:
            raise error_at(where, at("axis"), f"the {kind} joint's axis {list(axis)} has no direction; expected a "
                         "non-zero vector [x, y, z], at least 1e-6 long")
        return axis

    def limits_of(key: str, default: list[float], unit: str) -> tuple[float, float]:
        lo, hi = (float(v) for v in d.get(key, default))
        if lo > hi:
            raise error_at(where, at(key), f"the {kind} joint's limits [{lo:g}{unit}, {hi:g}{unit}] are reversed; "
                         "expected [lo, hi] with lo no greater than hi")
        return lo, hi

    if kind == "fixed":
        return Joint(base=base)
    if kind == "free":
        return FreeJoint(type="free", base=base)
    if kind == "rests_on":
        s, t = d.get("position", [0.0, 0.0])
        return RestsOnJoint(type="rests_on", face=d.get("face"), s=float(s), t=float(t),
                            yaw=float(np.radians(d.get("yaw_deg", 0.0))))
    if kind == "flush":
        s, t = d.get("position", [0.0, 0.0])
        off = d.get("offset", 0.0)
        if isinstance(off, bool) or not isinstance(off, int | float) or not np.isfinite(off):
            raise error_at(where, at("offset"), f"the flush joint's offset {off!r} is not a number; expected the "
                           "distance in metres between the two faces (0 for faces in contact)")
        own = d.get("own_face", "bottom")
        if not isinstance(own, str):
            raise error_at(where, at("own_face"), f"own_face {own!r} is not a face name; expected one of the "
                           "node's flat faces, such as \"back\"")
        return FlushJoint(type="flush", face=d.get("face"), own_face=own, offset=float(off), s=float(s),
                          t=float(t), yaw=float(np.radians(d.get("yaw_deg", 0.0))))
    if kind == "hinge":
        axis = axis_of([0, 0, 1])
        lo, hi = np.radians(limits_of("limits_deg", [-180.0, 180.0], "°"))
        angle = float(np.radians(d.get("angle_deg", 0.0)))
        if not lo <= angle <= hi:
            raise error_at(where, at("angle_deg"), f"hinge angle {np.degrees(angle):.1f}° lies outside its limits "
                         f"[{np.degrees(lo):.1f}°, {np.degrees(hi):.1f}°]")
        jamb = None
        if "jamb" in d:
            jamb = jamb_of(d["jamb"], where, at("jamb"))
        return HingeJoint(type="hinge", base=base, axis_point=np.asarray(d.get("axis_point", [0, 0, 0]), float),
                          axis=axis, angle=angle, limits=(float(lo), float(hi)), jamb=jamb,
                          solve_axis=_solve_axis_flag(d, where, path))
    if kind == "slider":
        axis = axis_of([1, 0, 0])
        lo, hi = limits_of("limits", [-np.inf, np.inf], " m")
        off = float(d.get("offset", 0.0))
        if not lo <= off <= hi:
            raise error_at(where, at("offset"), f"slider offset {off} lies outside its limits [{lo}, {hi}]")
        return SliderJoint(type="slider", base=base, axis=axis, offset=off, limits=(float(lo), float(hi)),
                           solve_axis=_solve_axis_flag(d, where, path))
    if kind == "marker":
        name = d.get("marker", "")
        if markers is None or name not in markers:
            raise error_at(where, at("marker"), f"the joint ties the node to marker '{name}', which has no calibrated "
                         "position; run vebuild calibrate first, or name a marker the calibration placed")
        return MarkerJoint(type="marker", marker=name, handle=d.get("handle", ""),
                           position=np.asarray(markers[name], float), yaw=float(np.radians(d.get("yaw_deg", 0.0))))
    if kind in ("opening", "through"):
        return room_joint_from_dict(d, where, path, base)
    raise error_at(where, at("type"), f"joint type '{kind}' is not one of {', '.join(JOINT_TYPES)}")
