"""The report's sections, each ``section(project, report)``: the photographs, the calibration, the
model and its solve, the evidence views, how well the model explains each photo, the recorded
analyses (:mod:`vebuild.report.analyses`) and the hypotheses."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

from vebuild.project import Project
from vebuild.project.units import RELATIVE_UNITS, length_unit
from vebuild.render.sizes import IMAGE_WIDTH, image_size

from .cameras import calibration, final_cameras
from .page import Cell, Report, esc, fmt, still_words, table

if TYPE_CHECKING:
    from vebuild.analysis.measure import CheckResult

__all__ = ["analyses", "calibration", "checks", "declaration", "final_cameras", "glossary", "hypotheses",
           "identification", "limitations", "marked_photos", "model", "photos", "validation", "views"]


def photos(project: Project, rep: Report) -> None:
    rows = []
    for p in project.data["photos"]:
        exif = p.get("exif") or {}
        camera = " ".join(x for x in (exif.get("make", ""), exif.get("model", "")) if x)
        rows.append([p["id"], p["file"], f"{p['width']}×{p['height']}", Cell(p["sha256"], "hash"), camera or "—",
                     fmt(exif.get("focal_length_mm"), 1) if exif.get("focal_length_mm") else "—"])
    rep.add("Photographs", "<p>Each photo as added to the project; vebuild refuses any photo whose bytes no longer "
            "hash to this SHA-256.</p>" + table(["id", "file", "pixels", "SHA-256", "camera", "focal mm"], rows,
                                                {2, 5}, wide=True) + _stills(project))


def _stills(project: Project) -> str:
    """The photos that are stills from video: the video, its SHA-256, the frame's index and time, the field."""
    from vebuild.project.stills import origin_summary

    rows = []
    for p in project.data["photos"]:
        if (o := origin_summary(p)) is not None:
            field = o["field"] if o["field"] != "both" else "both (whole frame)"
            rows.append([p["id"], o["video"], Cell(o["sha256"], "hash"), str(o["frame"]), fmt(o["time"], 3),
                         field, "yes" if o["interlaced"] else "no", o["decoder"]])
    if not rows:
        return ""
    return ("<p>Stills from video: each decoded exactly from the frame named (its index from 0 in presentation "
            "order, and its presentation time) and written as a lossless PNG, whose hash is the one above; the "
            "video's own SHA-256 traces it to its source. One field of an interlaced frame keeps that field's rows "
            "exactly and interpolates the others.</p>"
            + table(["id", "video", "video SHA-256", "frame", "time s", "field", "interlaced", "decoder"], rows,
                    {3, 4}, wide=True))


def model(project: Project, rep: Report) -> None:
    from vebuild.analysis.solved import check_model_solution

    from .limitations import entered_values

    check_model_solution(project)
    sol = project.data.get("model_solution")
    if not sol:
        rep.add("Model", "<p class='warn'>The model has not been solved (`vebuild solve`).</p>")
        return
    unit = length_unit(project.data)
    entered = entered_values(project)
    rows = []
    for node, rec in sol["nodes"].items():
        for group in ("params", "dofs"):
            for name, v in (rec.get(group) or {}).items():
                e = entered.get((node, name))
                if v.get("determined_by") == "relation":
                    rows.append([node, name, fmt(v["value"] + 0.0), Cell(f"held by relation {v.get('held_by', '')}",
                                                                        "entered"), "—", "—"])
                elif v.get("determined_by") == "observations and entered values":
                    ci = v.get("ci95") or [None, None]
                    rows.append([node, name, fmt(v["value"]), "from the photos, measured from entered values",
                                 fmt(v["sigma"]), f"{fmt(ci[0])} – {fmt(ci[1])}"])
                elif v.get("determined_by") == "entered value":
                    # No photo shows it: its value and σ are the entered values' (FORMAT.md determined_by).
                    ci = v.get("ci95") or [None, None]
                    rows.append([node, name, fmt(v["value"]), Cell("entered value only (no photo shows it)",
                                                                   "entered"),
                                 fmt(v["sigma"]), f"{fmt(ci[0])} – {fmt(ci[1])}"])
                elif e is not None:
                    # An entered value is no measurement: its σ is the one entered (none: taken as exact).
                    sigma = f"{fmt(e.sigma)} (entered)" if e.sigma > 0 else "none (taken as exact)"
                    rows.append([node, name, fmt(v["value"]), Cell("entered", "entered"), sigma, "—"])
                elif not v.get("sigma"):
                    rows.append([node, name, fmt(v["value"]), Cell("held by its joint, not solved", "entered"),
                                 "—", "—"])
                else:
                    ci = v.get("ci95") or [None, None]
                    rows.append([node, name, fmt(v["value"]), "from the photos", fmt(v["sigma"]),
                                 f"{fmt(ci[0])} – {fmt(ci[1])}"])
    how = "with" if sol.get("recalibrated") else "without"
    body = (f"<p>Primitives fitted to the pins and edges (paper §3), {how} "
            f"re-calibration of the cameras; RMS residual {fmt(sol.get('rms_px'), 2)} px, variance factor of "
            f"the clicks {fmt(sol.get('variance_factor'), 2)}. "
            + (f"Lengths in {RELATIVE_UNITS} (no scale was given), " if unit.relative else "Lengths in metres, ")
            + "angles in degrees; 1σ and 95 % interval from the solve's covariance. A value marked 'entered' was "
            "entered (a tape, a plan, an assumption), not measured in the photos: its σ is the entered one; "
            "one 'held by its joint' or 'held by relation' is no measurement either; one 'entered value only' is "
            "solved, but only entered values determine it (no photo shows it); one 'measured from entered values' "
            "is measured in the photos from what only entered values place (a position on a floor whose size was "
            "entered).</p>"
            + table(["node", "parameter", "value", "from", "1σ", "95 % interval"], rows, {2, 4, 5}, wide=True))
    outliers = sol.get("outliers") or []
    body += f"<p>Observations flagged as outliers (> 4σ): {len(outliers)}.</p>"
    if outliers:
        body += "<pre class='small'>" + esc(json.dumps(outliers, indent=1)[:4000]) + "</pre>"
    rep.add("Model", body)


def final_checks(project: Project) -> list[CheckResult]:
    """The check distances measured on the final model ([] before a solve, or without a scale)."""
    from vebuild.analysis.measure import check_distances
    from vebuild.analysis.solved import SolvedModel

    if not project.data.get("model_solution") or length_unit(project.data).relative:
        return []
    return check_distances(project, SolvedModel.from_project(project), roles=("check", "scale"))


def checks(project: Project, rep: Report) -> None:
    """Reference and check distances measured on the final model, each with its verdict."""
    refs = project.data.get("reference_distances") or []
    if not refs:
        return
    unit = length_unit(project.data)
    if unit.relative:
        stage = {frozenset((d["a"], d["b"])): d
                 for d in (project.data.get("calibration") or {}).get("reference_distances", [])}
        rows = [[f"{d['a']} – {d['b']}", d["role"], fmt(d["distance"]),
                 fmt(stage.get(frozenset((d["a"], d["b"])), {}).get("measured")),
                 fmt(stage.get(frozenset((d["a"], d["b"])), {}).get("measured_sigma"))] for d in refs]
        rep.add("Reference and check distances", "<p>Known at the scene in metres, measured here in "
                f"{RELATIVE_UNITS} (by the calibration stage): they are not compared.</p>"
                + table(["between", "role", "known m", "measured rel.", "1σ rel."], rows, {2, 3, 4}))
        return
    if not project.data.get("model_solution"):
        rep.add("Reference and check distances", "<p class='warn'>The model has not been solved: the distances "
                "are measured on the final model, after `vebuild solve`.</p>")
        return
    cal = {frozenset((d["a"], d["b"])): d
           for d in (project.data.get("calibration") or {}).get("reference_distances", [])}
    rows = []
    for c in sorted(rep.checks, key=lambda c: c.role != "check"):
        lo, hi = c.difference_ci95
        verdict = (Cell("within", "good") if c.within_ci95 else Cell("OUTSIDE", "bad"))
        stage = cal.get(frozenset((c.a, c.b)), {})
        before = (f"{1000 * (stage['measured'] - stage['distance']):+.1f}" if stage.get("measured") is not None
                  else "—")
        rows.append([f"{c.a} – {c.b}", c.role, fmt(c.known), fmt(c.measured.value), f"{1000 * c.measured.sigma:.1f}",
                     f"{1000 * c.difference:+.1f}", f"{1000 * c.difference_sigma:.1f}",
                     f"{1000 * lo:+.1f} … {1000 * hi:+.1f}", verdict, before])
    failed = [c for c in rep.checks if c.role == "check" and not c.within_ci95]
    body = ("<p>Each known distance measured on the final model (its cameras and markers as the solve left them; "
            "an end may be a marker or a model vertex, node:handle). The difference is measured − known; its 1σ "
            "combines the measurement's and the tape's; the verdict says whether the known distance lies within "
            "the 95 % interval of the measurement (the difference within ± 1.96σ of zero). 'check' distances were "
            "not used by the solve: they are the independent accuracy check; 'scale' distances fixed the scale, "
            "so their agreement proves little. The last column is the calibration stage's difference, before the "
            "model was solved, for comparison only.</p>"
            + (f"<p class='warn'>{len(failed)} check distance(s) outside the 95 % interval: the model is less "
               "accurate there than its σ says.</p>" if failed else "")
            + table(["between", "role", "known m", "measured m", "1σ mm", "difference mm", "1σ mm",
                     "95 % interval mm", "verdict", "calibration stage mm"], rows, {2, 3, 4, 5, 6, 7, 9}, wide=True))
    rep.add("Reference and check distances", body)


def limitations(project: Project, rep: Report) -> None:
    """What the figures rest on that no photo showed (:func:`vebuild.report.limitations.limitations`)."""
    from vebuild.project.provenance import stale

    from .limitations import limitations as items
    from .limitations import limitations_html

    found = stale(project.data, project.path.name)
    rep.add("Limitations", "<p>Made from the project itself: what an examiner should know before relying on "
            "the figures and images of this report.</p>" + limitations_html(items(project, rep.checks, found)))


def identification(project: Project, rep: Report) -> None:
    """What identifies the work (:func:`vebuild.report.page.identification`), first in the annex."""
    from .page import identification as rows

    rep.add("Identification", rows(project))


def declaration(project: Project, rep: Report) -> None:
    """The examiner's declaration (FORMAT.md ``case.declaration``), as written, closing the body."""
    text = (project.data.get("case") or {}).get("declaration")
    if text:
        rep.add("Declaration", f"<div class='declaration'>{esc(text)}</div>")


def glossary(project: Project, rep: Report) -> None:
    """The technical terms the annex keeps, in plain words (:mod:`vebuild.report.glossary`)."""
    from .glossary import glossary_html

    rep.add("Glossary", glossary_html())


def marked_photos(project: Project, rep: Report) -> None:
    """Each photo with the operator's marks drawn over it (:mod:`vebuild.report.marked_photos`)."""
    from .marked_photos import marked_photo

    figs = []
    for i, p in enumerate(project.data["photos"]):
        pixels, n = marked_photo(project, i, IMAGE_WIDTH)
        src = rep.image(f"marks-{i + 1}.png", pixels, {"Software": "vebuild", "Source": p["file"],
                                                       "Source SHA-256": p["sha256"]})
        extra = "".join(f", {k} {what}{'s' if k > 1 else ''}{how}" for k, what, how in (
            (n["rejected"], "vanishing segment", " left out by the calibration (grey, crossed)"),
            (n["known_lengths"], "known length", " (white)")) if k)
        figs.append(f"<figure><img src='{src}'><figcaption>photo {esc(p['id'])} ({esc(p['file'])}) as marked: "
                    f"{n['segments']} vanishing segments (x red, y green, z blue, arrow at the positive end)"
                    f"{esc(extra)}, {n['markers']} marker observations (orange rings), {n['pins']} pins (yellow "
                    f"crosses), {n['edges']} edge observations (magenta){esc(still_words(p))}</figcaption></figure>")
    rep.add("The photos as marked", "<p>Each original photo, reduced to this page, with every mark the operator "
            "made on it: what the calibration and the solve were given.</p>" + "".join(figs))


def _renderer(project: Project, scene: Any = None) -> tuple[Any, Any]:
    from vebuild.gl import headless_context
    from vebuild.render.renderer import Renderer, RenderOptions
    from vebuild.render.scene import load_scene

    scene = scene or load_scene(project)
    return scene, Renderer(headless_context(), scene, RenderOptions())


def views(project: Project, rep: Report) -> None:
    from vebuild.analysis.markers import draw_markers, visible_markers
    from vebuild.project.decode import view_camera
    from vebuild.render.observed import LEGEND_TEXT, UNOBSERVED_SRGB, finish_image
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
            text = provenance(project, cam, "view", "as-photographed", None, scene.page_hashes, {"samples": 4})
            img = finish_image(img, renderer.unobserved, renderer.marks_unobserved, text, scene.mask_hashes)
            src = rep.image(f"view-{i + 1}.png", img, text)
            eye = esc(unit.after(fmt(v["position"], 2)))
            parts.append(f"<figure><img src='{src}'><figcaption>{esc(v['name'])}: eye at {eye}"
                         f"{', ' + esc(v['description']) if v.get('description') else ''}</figcaption></figure>")
    finally:
        renderer.release()
    body = "".join(parts)
    if renderer.marks_unobserved:
        r, g, b = UNOBSERVED_SRGB
        body = (f"<p><span style='display:inline-block;width:1.2em;height:0.8em;background:rgb({r},{g},{b})'>"
                f"</span> {esc(LEGEND_TEXT[renderer.unobserved])}; the key is in each image's lower left corner "
                "(see Limitations for the faces).</p>" + body)
    if markers:
        body += "<h3>Evidence markers</h3>" + table(
            ["label", "on", f"position {unit.symbol}", "description"],
            [[m["label"], m["node"], fmt(m["position"], 3), m.get("description", "")] for m in markers])
    rep.add("Evidence views", body)


def validation(project: Project, rep: Report) -> None:
    from vebuild.actions.render import RenderRequest, render_evidence

    rows, figs = [], []
    from vebuild.project.decode import camera_records

    cams = camera_records(project.data)  # the final cameras
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
            "final camera (re-calibrated where the solve re-calibrated it), over the pixels the model covers, "
            "after one exposure gain.</p>"
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
