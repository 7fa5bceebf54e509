"""The report's sections, each ``section(project, report)``: the photographs, the calibration, the
model and its solve, the evidence views, how well the model explains each photo, the recorded
analyses (:mod:`vebuild.report.analyses`) and the hypotheses."""

from __future__ import annotations

import json
from typing import Any

from vebuild.project import Project
from vebuild.project.units import RELATIVE_UNITS, length_unit
from vebuild.render.sizes import IMAGE_WIDTH, image_size

from .page import Report, esc, fmt, table


def photos(project: Project, rep: Report) -> None:
    rows = []
    for p in project.data["photos"]:
        exif = p.get("exif") or {}
        camera = " ".join(x for x in (exif.get("make", ""), exif.get("model", "")) if x)
        rows.append([p["id"], p["file"], f"{p['width']}×{p['height']}", p["sha256"], camera or "—",
                     fmt(exif.get("focal_length_mm"), 1) if exif.get("focal_length_mm") else "—"])
    rep.add("Photographs", "<p>Each photo as added to the project; vebuild refuses any photo whose bytes no longer "
            "hash to this SHA-256.</p>" + table(["id", "file", "pixels", "SHA-256", "camera", "focal mm"], rows))


def _lens(camera: dict) -> str:
    """A camera record's lens distortion in words: k1 ± 1σ and the corner displacement, or pinhole."""
    d = camera.get("distortion")
    if not d:
        return "pinhole"
    k1, corner = d["k1"], d.get("corner_displacement_px") or {}
    text = f"k1 {k1['value']:+.4f} ± {k1['sigma'] or 0:.4f}"
    if corner:
        text += f", corners {corner['value']:.1f} ± {corner.get('sigma') or 0:.1f} px"
    return text + f" ({d.get('source', '')})"


def calibration(project: Project, rep: Report) -> None:
    cal = project.data["calibration"]
    unit = length_unit(project.data)
    rows = []
    for pid, c in cal["cameras"].items():
        rows.append([pid, c.get("mode", ""), f"{c['focal_px']['value']:.1f} ± {c['focal_px']['sigma'] or 0:.1f}",
                     fmt(c["principal_point"]["value"], 1),
                     " / ".join(f"{v:.2f} ± {s or 0:.2f}" for v, s in zip(c["ypr_deg"]["value"],
                                                                          c["ypr_deg"]["sigma"], strict=True)),
                     " / ".join(f"{v:.3f} ± {s or 0:.3f}" for v, s in zip(c["position"]["value"],
                                                                          c["position"]["sigma"], strict=True)),
                     _lens(c), fmt(c.get("rms_px"), 2)])
    body = ("<p>Cameras from vanishing points and markers (paper §2); values ± 1σ. The lens is the division "
            "model's k1 (x_u = x_d / (1 + k1 |x_d|²) on f-normalised coordinates; k1 &lt; 0 barrel) and how far "
            "it moves the photo's farthest corner; a pinhole where no distortion was estimated or given.</p>"
            + (f"<p class='warn'>{esc(unit.note)}.</p>" if unit.relative else "")
            + table(["photo", "mode", "focal px", "principal point px", "yaw / pitch / roll °",
                     f"position x / y / z {unit.symbol}", "lens", "RMS residual px"], rows))
    dist_rows = [[f"{d['a']} – {d['b']}", d["role"], fmt(d["distance"]), fmt(d.get("measured")),
                  fmt(d.get("measured_sigma")),
                  fmt(None if d.get("measured") is None else d["measured"] - d["distance"])]
                 for d in cal.get("reference_distances", [])]
    if dist_rows and unit.relative:
        body += ("<h3>Reference and check distances</h3><p>Known at the scene in metres, measured here in "
                 f"{RELATIVE_UNITS}: they are not compared.</p>"
                 + table(["between", "role", "known m", "measured rel.", "1σ rel."],
                         [r[:5] for r in dist_rows], {2, 3, 4}))
    elif dist_rows:
        body += ("<h3>Reference and check distances</h3><p>'scale' distances fix the metric scale; 'check' "
                 "distances are not used by the solve: measured against known, they are the independent accuracy "
                 "check.</p>" + table(["between", "role", "known m", "measured m", "1σ m", "difference m"], dist_rows,
                                      {2, 3, 4, 5}))
    rep.add("Calibration", body)


def model(project: Project, rep: Report) -> None:
    from vebuild.analysis.solved import check_model_solution

    check_model_solution(project)
    sol = project.data.get("model_solution")
    if not sol:
        rep.add("Model", "<p class='warn'>The model has not been solved (`vebuild solve`).</p>")
        return
    unit = length_unit(project.data)
    rows = []
    for node, rec in sol["nodes"].items():
        for group in ("params", "dofs"):
            for name, v in (rec.get(group) or {}).items():
                ci = v.get("ci95") or [None, None]
                rows.append([node, name, fmt(v["value"]), fmt(v["sigma"]), f"{fmt(ci[0])} – {fmt(ci[1])}"])
    how = "with" if sol.get("recalibrated") else "without"
    body = (f"<p>Primitives fitted to the pins and edges (paper §3), {how} "
            f"re-calibration of the cameras; RMS residual {fmt(sol.get('rms_px'), 2)} px, variance factor "
            f"{fmt(sol.get('variance_factor'), 2)}. "
            + (f"Lengths in {RELATIVE_UNITS} (no scale was given), " if unit.relative else "Lengths in metres, ")
            + "angles in degrees; 1σ and 95 % interval from the solve's covariance.</p>"
            + table(["node", "parameter", "value", "1σ", "95 % interval"], rows, {2, 3}))
    outliers = sol.get("outliers") or []
    body += f"<p>Observations flagged as outliers (> 4σ): {len(outliers)}.</p>"
    if outliers:
        body += "<pre class='small'>" + esc(json.dumps(outliers, indent=1)[:4000]) + "</pre>"
    rep.add("Model", body)


def _renderer(project: Project, scene: Any = None) -> tuple[Any, Any]:
    from vebuild.gl import headless_context
    from vebuild.render.renderer import Renderer, RenderOptions
    from vebuild.render.scene import load_scene

    scene = scene or load_scene(project)
    return scene, Renderer(headless_context(), scene, RenderOptions())


def views(project: Project, rep: Report) -> None:
    from vebuild.analysis.markers import draw_markers, visible_markers
    from vebuild.project.decode import view_camera
    from vebuild.render.png import provenance
    from vebuild.render.sizes import check_camera

    views = project.data.get("views", [])
    if not views:
        rep.add("Evidence views", "<p>The project has no named views.</p>")
        return
    cams = []  # every image's size checked before anything is drawn
    for i, v in enumerate(views):
        cam = view_camera(v, f"$.views[{i}]")
        cam = cam.resized(*image_size(cam.width, cam.height),
                          source=f"the report's image of view {v['name']!r} ({IMAGE_WIDTH} pixels wide, its "
                          f"height from the aspect of $.views[{i}], {cam.width}×{cam.height})")
        check_camera(cam)
        cams.append(cam)
    scene, renderer = _renderer(project)
    rep.warnings += scene.warnings
    markers = project.data.get("evidence_markers", [])
    unit = length_unit(project.data)
    parts = []
    try:
        for i, (v, cam) in enumerate(zip(views, cams, strict=True)):
            img = renderer.render(cam)
            img = draw_markers(img, visible_markers(renderer, cam, markers))
            src = rep.image(f"view-{i + 1}.png", img, provenance(project, cam, "view", "as-photographed", None,
                                                                scene.page_hashes, {"samples": 4}))
            eye = esc(unit.after(fmt(v["position"], 2)))
            parts.append(f"<figure><img src='{src}'><figcaption>{esc(v['name'])}: eye at {eye}"
                         f"{', ' + esc(v['description']) if v.get('description') else ''}</figcaption></figure>")
    finally:
        renderer.release()
    body = "".join(parts)
    if markers:
        body += "<h3>Evidence markers</h3>" + table(
            ["label", "on", f"position {unit.symbol}", "description"],
            [[m["label"], m["node"], fmt(m["position"], 3), m.get("description", "")] for m in markers])
    rep.add("Evidence views", body)


def validation(project: Project, rep: Report) -> None:
    from vebuild.actions.render import RenderRequest, render_evidence

    rows, figs = [], []
    cams = project.data["calibration"]["cameras"]
    for i, p in enumerate(project.data["photos"]):
        if p["id"] not in cams:
            continue
        tmp = rep.folder / "images" / f"photo-{i + 1}.png"
        size = image_size(p["width"], p["height"])
        res = render_evidence(project, RenderRequest(
            out=tmp, photo=p["id"], size=size, validate=True, markers=False,
            size_source=f"the report's image of photo {p['id']!r} ({IMAGE_WIDTH} pixels wide, its height from "
                        f"the aspect of $.photos[{i}], {p['width']}×{p['height']})"))
        tmp.unlink()
        assert res.overlay is not None and res.covered_fraction is not None  # validate=True
        rep.images.append(res.overlay)
        rows.append([p["id"], fmt(res.rms_colour_difference, 1), f"{100 * res.covered_fraction:.0f} %",
                     fmt(res.exposure_gain, 3)])
        figs.append(f"<figure><img src='images/{res.overlay.name}'><figcaption>photo {esc(p['id'])} and the model "
                    "rendered from its camera, half and half where the model covers it</figcaption></figure>")
    rep.add("How well the model explains each photo",
            "<p>RMS colour difference (sRGB levels, 0–255) between each photo and the model rendered from its "
            "calibrated camera, over the pixels the model covers, after one exposure gain.</p>"
            + table(["photo", "RMS difference", "covered", "gain"], rows, {1, 2, 3}) + "".join(figs))


def analyses(project: Project, rep: Report) -> None:
    """The analyses recorded in the project (FORMAT.md ``analyses``), each run again."""
    from .analyses import analyses_html

    records = project.data.get("analyses") or []
    if records:
        rep.add("Analyses", analyses_html(project, rep, records))


def hypotheses(project: Project, rep: Report) -> None:
    from vebuild.actions.render import RenderRequest, render_evidence
    from vebuild.project.hypotheses import label

    hyps = project.data.get("hypotheses", [])
    if not hyps:
        return
    views = project.data.get("views", [])
    parts = ["<p class='hyp'>HYPOTHESES: arrangements that are not the measured scene.</p>"]
    for i, h in enumerate(hyps):
        parts.append(f"<h3><span class='hyp'>{esc(label(h['name']))}</span></h3>")
        if h.get("description"):
            parts.append(f"<p>{esc(h['description'])}</p>")
        parts.append(table(["object", "joint in this hypothesis"],
                           [[n, json.dumps(j, sort_keys=True)] for n, j in h["joints"].items()]))
        if views:
            path = rep.folder / "images" / f"hypothesis-{i + 1}.png"
            size = image_size(views[0]["width"], views[0]["height"])
            render_evidence(project, RenderRequest(
                out=path, view=views[0]["name"], hypothesis=h["name"], size=size,
                size_source=f"the report's image of hypothesis {h['name']!r} ({IMAGE_WIDTH} pixels wide, its "
                            f"height from the aspect of $.views[0], {views[0]['width']}×{views[0]['height']})"))
            rep.images.append(path)
            parts.append(f"<figure><img src='images/{path.name}'><figcaption>{esc(label(h['name']))}, from view "
                         f"{esc(views[0]['name'])}</figcaption></figure>")
    rep.add("Hypotheses", "".join(parts))
