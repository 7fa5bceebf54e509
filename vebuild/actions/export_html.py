"""``vebuild export PROJECT --html DIR``: the web viewer folder (:mod:`vebuild.render.html`), with the
project's recorded analyses (FORMAT.md ``analyses``) run again, as the report runs them, so that
the page shows what the project gives now: each measurement as a segment between its points
labelled with its value, 1σ and 95 % interval, each trajectory as its path and 95 % cone labelled
with its direction and cone; other analyses (sight lines, viewsheds, lighting) are listed in the
page's panel with their table.

An analysis that cannot be run is a :class:`~vebuild.errors.ProjectError` naming
``$.analyses[i].command``, as in the report: the page never shows a figure it could not compute.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from vebuild.errors import ProjectError, VebuildError
from vebuild.project import Project
from vebuild.render.html import HtmlResult, write_html

#: Point spacing of a trajectory's drawn polylines (m).
TRAJECTORY_STEP_M = 0.05


def _length(v: float, unit: Any) -> str:
    return f"{v:.4f} rel." if unit.relative else f"{v:.3f} m"


def _sigma(s: float | None, unit: Any) -> str:
    if s is None:
        return "σ unknown"
    return f"{s:.4f} rel." if unit.relative else f"{1000 * s:.1f} mm"


def _measurement_items(rec: dict[str, Any], figures: dict[str, Any], unit: Any) -> list[dict[str, Any]]:
    if figures.get("frame") is not None:  # a person-height: its vertical, foot point to head-top
        from .handoff import person_item

        it = person_item(rec, figures["frame"])
        ends = it["ends"]
        return [{"kind": it["kind"], "label": it["label"], "anchor": [(a + b) / 2 for a, b in zip(*ends, strict=True)],
                 "paths": [ends], "cone": []}]
    out = []
    for m in figures.get("measurements") or []:
        value, sigma, ci = m.get(unit.key("value")), m.get(unit.key("sigma")), m.get(unit.key("ci95"))
        pts = [p.get(unit.key("position")) for p in m.get("points") or []]
        pts = [[float(v) for v in p] for p in pts if p is not None]
        if m.get("entered_sigma") == 0:
            text = f"{rec['name']}: {_length(value, unit)} (entered, held exactly)"
        else:
            interval = f", 95 % [{ci[0]:.3f}, {ci[1]:.3f}]" if ci else ""
            text = f"{rec['name']}: {_length(value, unit)} ± {_sigma(sigma, unit)} (1σ){interval}"
        if m.get("quantity") == "height" and len(pts) == 1:
            pts = [pts[0], [pts[0][0], pts[0][1], 0.0]]  # down to the floor (z = 0)
        anchor = [sum(p[k] for p in pts) / len(pts) for k in range(3)] if pts else None
        out.append({"kind": m.get("quantity", "measurement"), "label": text, "anchor": anchor,
                    "paths": [pts] if len(pts) >= 2 else [], "cone": []})
    return out


def _trajectory_item(rec: dict[str, Any], request: Any, occ: Any, unit: Any) -> dict[str, Any]:
    from vebuild.analysis.trajectory import path_polylines

    tr = request.trajectory(occ)
    lines = path_polylines(tr, step_m=TRAJECTORY_STEP_M)
    cone = ""
    if tr.cone_deg:
        cone = f", 95 % cone half-angle {tr.cone_deg:.2f}°"
        if tr.sigma is not None:
            cone += f" (holes' 1σ {_sigma(tr.sigma[0], unit)}, {_sigma(tr.sigma[1], unit)})"
    text = f"{rec['name']}: azimuth {tr.azimuth_deg:.1f}°, elevation {tr.elevation_deg:.1f}°{cone}"
    if tr.stop is not None:
        text += f"; stops at {tr.stop.node}"
    return {"kind": "trajectory", "label": text, "anchor": [float(v) for v in tr.entry],
            "paths": [[[float(v) for v in p] for p in P] for P in lines["path"]],
            "cone": [[[float(v) for v in p] for p in P] for P in lines["cone"]]}


def analyses_for_page(project: Project) -> tuple[list[dict[str, Any]], list[tuple[str, bytes]]]:
    """The project's recorded analyses, each run again, as :func:`vebuild.render.html.write_html`
    draws them, and the images they make (``analyses/analysis-N.png``, N from 1), written for the
    page's folder instead of where the recorded command says (as the report does)."""
    import tempfile

    records = project.data.get("analyses") or []
    if not records:
        return [], []
    with tempfile.TemporaryDirectory(prefix="vebuild-html-") as tmp:
        return _analyses(project, records, Path(tmp))


def _analyses(project: Project, records: list[dict[str, Any]],
              tmp: Path) -> tuple[list[dict[str, Any]], list[tuple[str, bytes]]]:
    from vebuild.analysis.recorded import run_recorded
    from vebuild.analysis.requests_geometry import TrajectoryRequest
    from vebuild.project.units import length_unit

    unit = length_unit(project.data)
    occ = None
    out: list[dict[str, Any]] = []
    images: list[tuple[str, bytes]] = []
    for i, rec in enumerate(records):
        where = f"$.analyses[{i}]"
        words = list(rec["command"])
        image = f"analyses/analysis-{i + 1}.png"
        request, result = run_recorded(project, i, rec, str(tmp / f"analysis-{i + 1}.png"))
        try:
            if isinstance(request, TrajectoryRequest):
                if occ is None:
                    from vebuild.analysis.rays import Occluders
                    from vebuild.render.scene import load_scene

                    occ = Occluders(load_scene(project))
                items = [_trajectory_item(rec, request, occ, unit)]
            else:
                items = _measurement_items(rec, result.figures, unit)
        except VebuildError as e:
            raise ProjectError(project.path, f"{where}.command", str(e)) from None
        base = {"name": rec["name"], "description": rec.get("description", ""), "command": words,
                "analysis": request.name, "table": result.table.replace(str(tmp) + "/", ""), "image": None}
        if result.image is not None and result.image.is_file():
            images.append((image, result.image.read_bytes()))
            base["image"] = image
        if not items:  # a sight line, a viewshed, a lighting comparison: listed, not drawn
            items = [{"kind": request.name, "label": f"{rec['name']}: {request.name} (see its table)", "anchor": None,
                      "paths": [], "cone": []}]
        for item in items:
            out.append({**base, **item})
    return out, images


def export_html(project: Project, folder: str | os.PathLike[str], photo: str | None = None) -> HtmlResult:
    """Write the viewer folder ``folder`` for ``project``, its analyses run again. A project with no
    model is shown as its one calibrated photo (``photo``, or the only one): the photo at its
    camera, the floor grid, the axes and its single-view measurements (:mod:`vebuild.actions.handoff`)."""
    if not (project.data.get("model") or {}).get("nodes"):
        return _single_photo_html(project, Path(folder), photo)
    if photo is not None:
        raise VebuildError(f"--camera {photo}: the project has a model, and its viewer shows every photo; leave "
                           "out --camera (it is for a project with no model)")
    analyses, images = analyses_for_page(project)
    return write_html(project, Path(folder), analyses, extra_files=images)


def _single_photo_html(project: Project, folder: Path, photo: str | None) -> HtmlResult:
    from vebuild.project.decode import photo_camera

    from .handoff import calibrated_photo, camera_scene, measurement_items

    pid = calibrated_photo(project, photo)
    cam = photo_camera(project, pid)
    items = measurement_items(project, pid)
    doc, binary, _, _ = camera_scene(project, cam, items)
    analyses = [{"name": it["name"], "description": it["description"], "command": it["command"],
                 "analysis": it["analysis"], "table": it["table"], "image": None, "kind": it["kind"],
                 "label": it["label"], "anchor": [sum(p[k] for p in it["ends"]) / 2 for k in range(3)],
                 "paths": [it["ends"]], "cone": []} for it in items]
    return write_html(project, folder, analyses, camera_only=(doc, binary, cam))
