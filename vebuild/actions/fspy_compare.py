"""fSpy's own stored camera beside vebuild's calibration of the same photo from the same marks
(``vebuild import``; :mod:`vebuild.actions.fspy` makes the project, and
:mod:`vebuild.actions.fspy_command` prints the comparison)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ypr_from_rotation
from vebuild.project.fspy import UNITS_M, FspyProject, image_plane_to_pixels

Array = NDArray[np.float64]

#: fSpy's camera (OpenGL: y up, looking along −z) → vebuild's (y down, looking along +z), for
#: reading fSpy's stored view transform only; vebuild's own conversion to OpenGL is
#: :func:`vebuild.camera.gl_projection`.
GL_TO_CV = np.diag([1.0, -1.0, -1.0])


@dataclass
class ComparisonRow:
    quantity: str
    fspy: float | None
    vebuild: float | None
    sigma: float | None

    @property
    def difference(self) -> float | None:
        if self.fspy is None or self.vebuild is None:
            return None
        d = self.vebuild - self.fspy
        if "(°)" in self.quantity and self.quantity.startswith(("yaw", "roll")):
            d = (d + 180.0) % 360.0 - 180.0
        return d


@dataclass(frozen=True)
class FspyCameraInPixels:
    """fSpy's stored camera in vebuild's conventions (pixels, R world → camera, C in metres or in
    fSpy's units)."""

    f: float
    c: Array
    R: Array
    C: Array
    metric: bool


def fspy_camera_in_vebuild(fp: FspyProject) -> FspyCameraInPixels | None:
    cam = fp.camera
    if cam is None:
        return None
    W, H = fp.width, fp.height
    f = cam.relative_focal_length * max(W, H) / 2.0
    c = image_plane_to_pixels(cam.principal_point, W, H)
    V = cam.view_transform
    R = GL_TO_CV @ V[:3, :3]
    C = -V[:3, :3].T @ V[:3, 3]
    unit = UNITS_M[fp.reference_unit] if fp.reference_axis is not None else None
    return FspyCameraInPixels(f, c, R, C * (unit or 1.0), unit is not None)


def rotation_difference_deg(R1: Array, R2: Array) -> float:
    cos = (np.trace(R1 @ R2.T) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def comparison_rows(fp: FspyProject, data: dict[str, Any], pid: str, scaled: bool) -> list[ComparisonRow]:
    cal = data.get("calibration") or {}
    cam = (cal.get("cameras") or {}).get(pid) or (cal.get("unplaced") or {}).get(pid)
    if cam is None:
        return []
    W = fp.width
    fs = fspy_camera_in_vebuild(fp)
    f = cam["focal_px"]
    fv, fsig = float(f["value"]) if isinstance(f, dict) else float(f), (f.get("sigma") if isinstance(f, dict) else None)
    pp = cam["principal_point"]
    pv = pp["value"] if isinstance(pp, dict) else pp
    psig = pp.get("sigma") if isinstance(pp, dict) else None
    R = np.array(cam["R"], float)
    ypr_v = np.degrees(ypr_from_rotation(R))
    ysig = cam["ypr_deg"]["sigma"] if isinstance(cam.get("ypr_deg"), dict) else [None] * 3

    def fov(fx: float) -> float:
        return math.degrees(2 * math.atan(W / (2 * fx)))

    fov_sig = None if fsig is None else abs(fov(fv) - fov(fv + fsig))
    rows = [ComparisonRow("focal length (px)", fs.f if fs else None, fv, fsig),
            ComparisonRow("horizontal FOV (°)", fov(fs.f) if fs else None, fov(fv), fov_sig),
            ComparisonRow("principal point u (px)", float(fs.c[0]) if fs else None, float(pv[0]),
                          psig[0] if psig else None),
            ComparisonRow("principal point v (px)", float(fs.c[1]) if fs else None, float(pv[1]),
                          psig[1] if psig else None)]
    ypr_f = [float(a) for a in np.degrees(ypr_from_rotation(fs.R))] if fs else [None, None, None]
    for k, label in enumerate(("yaw", "pitch", "roll")):
        rows.append(ComparisonRow(f"{label} (°)", ypr_f[k], float(ypr_v[k]), ysig[k]))
    if fs is not None:  # the angle of the rotation that takes one camera's orientation to the other's
        rows.append(ComparisonRow("rotation between the two (°)", 0.0, rotation_difference_deg(R, fs.R), None))
    pos = cam.get("position")
    if isinstance(pos, dict) and scaled:
        for k, axis in enumerate("xyz"):
            rows.append(ComparisonRow(f"position {axis} (m)", float(fs.C[k]) if fs and fs.metric else None,
                                      float(pos["value"][k]), pos["sigma"][k]))
    return rows
