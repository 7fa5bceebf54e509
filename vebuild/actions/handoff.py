"""A calibrated photo handed on with no model (docs/export.md): ``vebuild export PROJECT --camera
PHOTO --out FILE.glb`` (the camera-only glTF, :mod:`vebuild.render.export_camera`) or ``--out
FILE.fspy`` (an fSpy project that fSpy and its Blender add-on open, :mod:`vebuild.project.fspy_write`),
and the measurements the web viewer draws for such a project.

The saved single-view measurements of the photo (``analyses`` records whose words are a
``vebuild analyse photo-height|floor-distance|wall-length|raised-height|plane-length --photo ID …``
command) are run again, as the report runs them, so that each line is labelled with what the
project gives now; each is drawn between the 3-D ends its clicks give
(:mod:`vebuild.analysis.single_view_lines`), whose length must equal the measured value.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.camera import ImageCamera
from vebuild.errors import ProjectError, VebuildError
from vebuild.project import Project
from vebuild.project.handoff_image import HandoffImage
from vebuild.render.export_camera import CameraScene

#: What ``--out`` may end in with ``--camera``.
CAMERA_FORMATS = {".glb": "glTF 2.0 binary (camera, photo plane, floor grid, axes, measurements)",
                  ".fspy": "fSpy project (fSpy and its Blender add-on open it)"}


@dataclass
class HandoffResult:
    path: Path
    format: str  # "glb" or "fspy"
    photo: str
    measurements: int
    details: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def calibrated_photo(project: Project, photo: str | None) -> str:
    """The id of the calibrated photo to hand on: ``photo``, or the only calibrated one."""
    from vebuild.project.decode import camera_records

    calibrated = [p["id"] for p in project.data.get("photos", []) if p["id"] in camera_records(project.data)]
    ids = [p["id"] for p in project.data.get("photos", [])]
    if photo is None:
        if len(calibrated) == 1:
            return calibrated[0]
        if not calibrated:
            raise VebuildError(f"{project.path}: no photo is calibrated yet; run `vebuild calibrate {project.path}` "
                               "first")
        raise VebuildError(f"{project.path}: {len(calibrated)} photos are calibrated ({', '.join(calibrated)}); say "
                           "which with --camera PHOTO")
    if photo not in ids:
        raise VebuildError(f"--camera {photo}: the project has no photo {photo!r}; its photos are "
                           f"{', '.join(ids) or 'none'}")
    if photo not in calibrated:
        raise VebuildError(f"--camera {photo}: photo {photo!r} is not calibrated yet; run `vebuild calibrate "
                           f"{project.path}` first (calibrated: {', '.join(calibrated) or 'none'})")
    return photo


def _length(v: float, relative: bool) -> str:
    return f"{v:.4f} rel." if relative else f"{v:.3f} m"


def _sigma(s: float | None, relative: bool) -> str:
    if s is None:
        return "σ unknown"
    return f"{s:.4f} rel." if relative else f"{1000 * s:.1f} mm"


def measurement_items(project: Project, photo: str) -> list[dict[str, Any]]:
    """The photo's saved single-view measurements, run again: for each measured line its label
    (value, 1σ, 95 % interval), world ends, figures and the record's name and words."""
    from vebuild.analysis.recorded import run_recorded
    from vebuild.analysis.single_view_lines import (
        command_photo_and_pixels,
        line_length_agrees,
        measured_lines,
        single_view_kind,
    )
    from vebuild.project.decode import photo_camera

    cam = None
    out: list[dict[str, Any]] = []
    for i, rec in enumerate(project.data.get("analyses") or []):
        words = list(rec.get("command") or [])
        if words[:1] == ["person-height"]:
            request, result = run_recorded(project, i, rec)
            frame = result.figures.get("frame")
            if frame is not None and frame["photo"] == photo:
                out.append({"name": rec["name"], "record": rec["name"], "description": rec.get("description", ""),
                            "analysis": request.name, "command": words, "table": result.table,
                            "lengths": "metres", "clicks": frame["clicks_px"], **person_item(rec, frame)})
            continue
        kind = single_view_kind(words)
        if kind is None:
            continue
        where = f"$.analyses[{i}].command"
        try:
            pid, pixels = command_photo_and_pixels(words)
        except VebuildError as e:
            raise ProjectError(project.path, where, str(e)) from None
        if pid != photo:
            continue
        request, result = run_recorded(project, i, rec)
        if cam is None:
            cam = photo_camera(project, photo)
        try:
            lines = measured_lines(cam, kind, pixels)
        except VebuildError as e:
            raise ProjectError(project.path, where, str(e)) from None
        relative = result.figures.get("lengths") == "relative"
        suffix = "_relative" if relative else "_m"
        rows = result.figures.get("measurements") or []
        if len(rows) != len(lines):
            raise ProjectError(project.path, where, f"the command gave {len(rows)} measurement(s) for "
                               f"{len(lines)} group(s) of clicks")
        for k, (line, m) in enumerate(zip(lines, rows, strict=True)):
            value, sigma, ci = m.get("value" + suffix), m.get("sigma" + suffix), m.get("ci95" + suffix)
            if not line_length_agrees(line, float(value)):
                raise ProjectError(project.path, where, f"measurement {k + 1}: the line drawn from its clicks is "
                                   f"{line.length:.6g} long but the measurement is {value:.6g}; this is a fault in "
                                   "vebuild: please report it with the project")
            name = rec["name"] if len(lines) == 1 else f"{rec['name']} ({k + 1})"
            interval = f", 95 % [{ci[0]:.3f}, {ci[1]:.3f}]" if ci else ""
            label = f"{name}: {_length(value, relative)} ± {_sigma(sigma, relative)} (1σ){interval}"
            out.append({"name": name, "record": rec["name"], "description": rec.get("description", ""),
                        "kind": m.get("quantity", line.quantity), "analysis": request.name, "label": label,
                        "command": words, "table": result.table, "value": float(value),
                        "sigma": None if sigma is None else float(sigma), "ci95": ci,
                        "lengths": "relative" if relative else "metres",
                        "ends": line.ends.tolist(), "clicks": line.clicks.tolist()})
    return out


def person_item(rec: dict[str, Any], frame: dict[str, Any]) -> dict[str, Any]:
    """A recorded person-height's frame (:meth:`vebuild.analysis.person.PersonFrame.to_json`) as a
    line to draw: the vertical measured, from the foot point on the floor to the height in the
    image, labelled with it and with the height the allowances make of it."""
    lo, hi = frame["ci95_m"]
    label = (f"{rec['name']}: {frame['image_height_m']:.3f} m ± {1000 * frame['sigma_image_m']:.1f} mm (1σ) in the "
             f"image; with the allowances entered {frame['value_m']:.3f} m, 95 % [{lo:.3f}, {hi:.3f}]")
    return {"kind": "height", "label": label, "value": float(frame["image_height_m"]),
            "sigma": float(frame["sigma_image_m"]), "ci95": [lo, hi], "ends": [frame["foot_m"], frame["top_m"]]}


def camera_scene(project: Project, cam: ImageCamera,
                 items: list[dict[str, Any]]) -> tuple[dict[str, Any], bytes, CameraScene, HandoffImage]:
    """The camera-only glTF document of ``cam`` with the measurement ``items``
    (:func:`measurement_items`), its binary chunk, what it holds and the photo's image."""
    from vebuild.project.handoff_image import handoff_image
    from vebuild.render.export_camera import MAX_TEXTURE_PX, SceneLine, camera_document

    image = handoff_image(project, cam.id, MAX_TEXTURE_PX)
    lines = [SceneLine(it["label"], np.asarray(it["ends"], float),
                       {k: it[k] for k in ("record", "kind", "analysis", "command", "value", "sigma", "ci95",
                                           "lengths", "clicks")}) for it in items]
    doc, binary, info = camera_document(project, cam, image, lines)
    return doc, binary, info, image


def export_camera(project: Project, photo: str | None, path: str | os.PathLike[str]) -> HandoffResult:
    """Write photo ``photo``'s camera (and its measurements) to ``path``: .glb or .fspy."""
    from vebuild.project.atomic import write_many
    from vebuild.project.outputs import begin_stage, check_file

    path = Path(path)
    fmt = path.suffix.lower()
    if fmt not in CAMERA_FORMATS:
        raise VebuildError(f"{path}: with --camera, expected a file name ending in "
                           + " or ".join(f"{k} ({v})" for k, v in CAMERA_FORMATS.items()))
    if path.is_dir():
        raise VebuildError(f"{path}: is a folder; give a file name ending in {fmt}")
    if not path.parent.is_dir():
        raise VebuildError(f"{path}: the output folder {path.parent} does not exist; create it first")
    pid = calibrated_photo(project, photo)
    check_file(project, path, "export")
    from vebuild.project.decode import photo_camera

    cam = photo_camera(project, pid)
    items = measurement_items(project, pid) if fmt == ".glb" else []
    warnings: list[str] = []
    if fmt == ".glb":
        from vebuild.project.units import length_unit

        unit = "rel." if length_unit(project.data).relative else "m"
        doc, binary, info, image = camera_scene(project, cam, items)
        from vebuild.render.export import glb_bytes

        data = glb_bytes(doc, binary)
        details = [f"camera 'photo {pid}' (yfov {math.degrees(doc['cameras'][0]['perspective']['yfov']):.2f}°, "
                   f"aspect {cam.width}:{cam.height}, principal point offset "
                   f"({cam.K[0][2] - cam.width / 2:+.1f}, {cam.K[1][2] - cam.height / 2:+.1f}) px)",
                   f"photo plane {info.plane_distance:.3g} {unit} in front of the camera, "
                   + (f"{info.plane_grid[0]}×{info.plane_grid[1]} cells" if not cam.lens.is_pinhole else "one quad")
                   + (f", lens undistorted (k1 {cam.lens.k1:+.4g}{_k2_words(cam.lens.k2)}) to within "
                      f"{info.plane_error_px:.3f} px"
                      if not cam.lens.is_pinhole else ""),
                   f"floor grid every {info.grid_spacing:g} over x {info.grid_bounds[0]:g}…{info.grid_bounds[1]:g}, "
                   f"y {info.grid_bounds[2]:g}…{info.grid_bounds[3]:g}; axes; {info.lines} measurement line(s)",
                   f"photo: {image.note}"]
    else:
        from vebuild.project.fspy_write import fspy_project

        data, details, warnings = fspy_project(project, pid, cam)
    begin_stage(project, path.parent)
    try:
        write_many([(path, data)])
    except OSError as e:
        raise VebuildError(f"{path}: cannot write it ({e.strerror or e}); nothing was written") from None
    return HandoffResult(path, fmt[1:], pid, len(items), details, warnings)


def export_camera_command(project: Project, photo: str | None, out: str) -> int:
    """``vebuild export --camera PHOTO --out FILE.glb|FILE.fspy`` (and ``--out`` on a project with no
    model): the hand-off written, and what it holds printed; the exit status."""
    r = export_camera(project, photo, out)
    what = {"glb": "glTF 2.0 binary, the calibrated camera with no model", "fspy": "fSpy project"}[r.format]
    drawn = f", {r.measurements} measurement(s)" if r.format == "glb" else ""
    print(f"wrote {r.path} ({what}, {r.path.stat().st_size / 1e6:.2f} MB): photo {r.photo}{drawn}")
    for line in r.details:
        print(f"  {line}")
    for w in r.warnings:
        print(f"warning: {w}")
    return 0


def _k2_words(k2: float) -> str:
    """", k2 +0.0123" for a two-term lens, nothing for one term."""
    return f", k2 {k2:+.4g}" if k2 != 0.0 else ""
