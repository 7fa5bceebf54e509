"""``vebuild report``: everything another examiner needs to check and reproduce the work, as an
HTML page with its images (and a PDF of it).

The report is made from the project file alone: the photos with their SHA-256, the calibration
and its residuals, the model and its solve, the check distances, the evidence views (with the
evidence markers), each photo's camera against its photo, the analyses the project records
(``analyses``: measurements, sight lines, viewsheds, trajectories, lighting comparisons, each
re-computed), and the hypotheses, each clearly labelled as one. It carries no time stamp: running
it twice on the same project gives the same HTML and the same images, byte for byte.
"""

from __future__ import annotations

import hashlib
import html
import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vebuild import __version__
from vebuild.errors import VebuildError
from vebuild.project import Project, sha256_file

#: Renders in the report are this wide (height from the view's aspect).
IMAGE_WIDTH = 960

CSS = """
body { font-family: DejaVu Sans, Helvetica, Arial, sans-serif; font-size: 10.5pt; margin: 2em; color: #111; }
h1 { font-size: 18pt; } h2 { font-size: 14pt; border-bottom: 1px solid #999; margin-top: 1.6em; }
h3 { font-size: 11.5pt; }
table { border-collapse: collapse; margin: 0.5em 0 1em 0; }
td, th { border: 1px solid #bbb; padding: 2px 6px; text-align: left; vertical-align: top; overflow-wrap: anywhere; }
th { background: #eee; } td.n { text-align: right; font-variant-numeric: tabular-nums; }
img { max-width: 100%; border: 1px solid #888; }
.hyp { color: #fff; background: #aa1414; padding: 2px 6px; font-weight: bold; }
.small { font-size: 9pt; color: #444; } .warn { color: #a05000; }
figure { margin: 0.5em 0 1.2em 0; page-break-inside: avoid; }
@page { size: A4; margin: 15mm; }
"""


@dataclass
class Report:
    folder: Path
    sections: list[str] = field(default_factory=list)
    images: list[Path] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def add(self, title: str, body: str) -> None:
        self.sections.append(f"<h2>{esc(title)}</h2>\n{body}")

    def image(self, name: str, pixels: np.ndarray, text: dict[str, str] | None = None) -> str:
        """Write an image into the report's folder; returns its relative path."""
        from vebuild.actions.render import write_png

        path = self.folder / "images" / name
        write_png(path, pixels, text or {})
        self.images.append(path)
        return f"images/{name}"


def esc(x: Any) -> str:
    return html.escape(str(x))


def fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "undetermined"
    if isinstance(v, list | tuple):
        return "(" + ", ".join(fmt(x, digits) for x in v) + ")"
    return f"{float(v):.{digits}f}"


def table(header: list[str], rows: list[list[Any]], numeric: set[int] | None = None) -> str:
    numeric = numeric or set()
    out = ["<table><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>"]
    for r in rows:
        out.append("<tr>" + "".join(f"<td class='n'>{esc(c)}</td>" if i in numeric else f"<td>{esc(c)}</td>"
                                    for i, c in enumerate(r)) + "</tr>")
    return "\n".join(out) + "</table>"


def write_report(project: Project, out: Path, pdf: bool = True,
                 progress: Callable[[str], None] | None = None) -> Path:
    """Write ``out/report.html`` (and ``out/report.pdf``) with its images in ``out/images``."""
    from vebuild.project.atomic import MANIFEST, remove_tree, replace_folder, temp_path, write_text
    from vebuild.project.outputs import SOFTWARE, begin_stage, check_folder, write_manifest

    given = Path(out)
    if not given.parent.is_dir():
        raise VebuildError(f"{given}: the folder {given.parent} does not exist; create it first")
    check_folder(project, given, "report")
    if not (project.data.get("calibration") or {}).get("cameras"):
        raise VebuildError(f"{project.path}: the project has no calibrated cameras yet; run `vebuild calibrate` "
                           "(and `vebuild solve`) before making a report")
    out = Path(os.path.abspath(given))
    begin_stage(project, out.parent)
    # Build under a fresh sibling name, then swap it in (vebuild.project.atomic.replace_folder): never a
    # half-written report, and the old one is deleted only once the new one is in place.
    tmp = temp_path(out)
    try:
        tmp.mkdir()
        # The manifest first (no files yet): it marks the folder as vebuild's should this run be killed.
        write_text(tmp / MANIFEST, json.dumps({"software": SOFTWARE, "kind": "report", "files": {}}) + "\n")
        (tmp / "images").mkdir()
        rep = Report(tmp)
        step = progress or (lambda what: None)
        steps = [("photos", _photos), ("calibration", _calibration), ("model", _model), ("views", _views),
                 ("validation", _validation), ("analyses", _analyses), ("hypotheses", _hypotheses)]
        for name, fn in steps:
            step(name)
            fn(project, rep)
        page = _page(project, rep)
        write_text(tmp / "report.html", page)
        if pdf:
            step("pdf")
            _pdf(tmp)
        write_manifest(tmp, "report", project)
        check_folder(project, given, "report")  # again: nothing of the user's was put there meanwhile
        replace_folder(tmp, out)
    except OSError as e:
        remove_tree(tmp)
        raise VebuildError(f"{given}: cannot write the report ({e.strerror or e}); the old one, if any, "
                           "is unchanged") from None
    except BaseException:
        remove_tree(tmp)
        raise
    return given / "report.html"


def _pdf(folder: Path) -> None:
    try:
        import weasyprint
    except ImportError as e:  # weasyprint needs Pango from the system
        raise VebuildError(f"cannot make the PDF ({e}); install Pango (`sudo apt-get install libpango-1.0-0 "
                           "libpangoft2-1.0-0`) or pass --no-pdf") from None
    doc = weasyprint.HTML(filename=str(folder / "report.html"), base_url=str(folder))
    doc.write_pdf(folder / "report.pdf", metadata=None, uncompressed_pdf=False)


def _page(project: Project, rep: Report) -> str:
    data = project.data
    head = [f"<h1>vebuild report: {esc(data.get('name', project.path.name))}</h1>",
            table(["", ""], [["project file", project.path.name], ["project file SHA-256", sha256_file(project.path)],
                             ["software", f"vebuild {__version__}"],
                             ["reproduce", f"vebuild report {project.path.name} --out DIR (the same project gives "
                                           "the same figures and images)"]])]
    if rep.warnings:
        head.append("<p class='warn'>" + "<br>".join(esc(w) for w in rep.warnings) + "</p>")
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>vebuild report: {esc(data.get('name', ''))}</title><style>{CSS}</style></head><body>\n"
            + "\n".join(head + rep.sections) + "\n</body></html>\n")


def _photos(project: Project, rep: Report) -> None:
    rows = []
    for p in project.data["photos"]:
        exif = p.get("exif") or {}
        camera = " ".join(x for x in (exif.get("make", ""), exif.get("model", "")) if x)
        rows.append([p["id"], p["file"], f"{p['width']}×{p['height']}", p["sha256"], camera or "—",
                     fmt(exif.get("focal_length_mm"), 1) if exif.get("focal_length_mm") else "—"])
    rep.add("Photographs", "<p>Each photo as added to the project; vebuild refuses any photo whose bytes no longer "
            "hash to this SHA-256.</p>" + table(["id", "file", "pixels", "SHA-256", "camera", "focal mm"], rows))


def _calibration(project: Project, rep: Report) -> None:
    cal = project.data["calibration"]
    rows = []
    for pid, c in cal["cameras"].items():
        rows.append([pid, c.get("mode", ""), f"{c['focal_px']['value']:.1f} ± {c['focal_px']['sigma'] or 0:.1f}",
                     fmt(c["principal_point"]["value"], 1),
                     " / ".join(f"{v:.2f} ± {s or 0:.2f}" for v, s in zip(c["ypr_deg"]["value"],
                                                                          c["ypr_deg"]["sigma"], strict=True)),
                     " / ".join(f"{v:.3f} ± {s or 0:.3f}" for v, s in zip(c["position"]["value"],
                                                                          c["position"]["sigma"], strict=True)),
                     fmt(c.get("rms_px"), 2)])
    body = ("<p>Cameras from vanishing points and markers (paper §2); values ± 1σ.</p>"
            + table(["photo", "mode", "focal px", "principal point px", "yaw / pitch / roll °",
                     "position x / y / z m", "RMS residual px"], rows))
    dist_rows = [[f"{d['a']} – {d['b']}", d["role"], fmt(d["distance"]), fmt(d.get("measured")),
                  fmt(d.get("measured_sigma")),
                  fmt(None if d.get("measured") is None else d["measured"] - d["distance"])]
                 for d in cal.get("reference_distances", [])]
    if dist_rows:
        body += ("<h3>Reference and check distances</h3><p>'scale' distances fix the metric scale; 'check' "
                 "distances are not used by the solve: measured against known, they are the independent accuracy "
                 "check.</p>" + table(["between", "role", "known m", "measured m", "1σ m", "difference m"], dist_rows,
                                      {2, 3, 4, 5}))
    rep.add("Calibration", body)


def _model(project: Project, rep: Report) -> None:
    from vebuild.analysis.measure import check_model_solution

    check_model_solution(project)
    sol = project.data.get("model_solution")
    if not sol:
        rep.add("Model", "<p class='warn'>The model has not been solved (`vebuild solve`).</p>")
        return
    rows = []
    for node, rec in sol["nodes"].items():
        for group in ("params", "dofs"):
            for name, v in (rec.get(group) or {}).items():
                ci = v.get("ci95") or [None, None]
                rows.append([node, name, fmt(v["value"]), fmt(v["sigma"]), f"{fmt(ci[0])} – {fmt(ci[1])}"])
    how = "with" if sol.get("recalibrated") else "without"
    body = (f"<p>Primitives fitted to the pins and edges (paper §3), {how} "
            f"re-calibration of the cameras; RMS residual {fmt(sol.get('rms_px'), 2)} px, variance factor "
            f"{fmt(sol.get('variance_factor'), 2)}. Lengths in metres, angles in degrees; 1σ and 95 % interval from "
            "the solve's covariance.</p>" + table(["node", "parameter", "value", "1σ", "95 % interval"], rows,
                                                  {2, 3}))
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


def image_size(width: int, height: int) -> tuple[int, int]:
    """The size of the report's image of a view or photo of ``width`` × ``height`` pixels:
    :data:`IMAGE_WIDTH` wide, its height from their aspect."""
    return IMAGE_WIDTH, max(1, round(IMAGE_WIDTH * height / width))


def _views(project: Project, rep: Report) -> None:
    from vebuild.actions.render import provenance
    from vebuild.analysis.markers import draw_markers, visible_markers
    from vebuild.project.decode import view_camera
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
    parts = []
    try:
        for i, (v, cam) in enumerate(zip(views, cams, strict=True)):
            img = renderer.render(cam)
            img = draw_markers(img, visible_markers(renderer, cam, markers))
            src = rep.image(f"view-{i + 1}.png", img, provenance(project, cam, "view", "as-photographed", None,
                                                                scene.page_hashes, {"samples": 4}))
            parts.append(f"<figure><img src='{src}'><figcaption>{esc(v['name'])}: eye at {fmt(v['position'], 2)} m"
                         f"{', ' + esc(v['description']) if v.get('description') else ''}</figcaption></figure>")
    finally:
        renderer.release()
    body = "".join(parts)
    if markers:
        body += "<h3>Evidence markers</h3>" + table(
            ["label", "on", "position m", "description"],
            [[m["label"], m["node"], fmt(m["position"], 3), m.get("description", "")] for m in markers])
    rep.add("Evidence views", body)


def _validation(project: Project, rep: Report) -> None:
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
        rep.images.append(res.overlay)
        rows.append([p["id"], fmt(res.rms_colour_difference, 1), f"{100 * res.covered_fraction:.0f} %",
                     fmt(res.exposure_gain, 3)])
        figs.append(f"<figure><img src='images/{res.overlay.name}'><figcaption>photo {esc(p['id'])} and the model "
                    "rendered from its camera, half and half where the model covers it</figcaption></figure>")
    rep.add("How well the model explains each photo",
            "<p>RMS colour difference (sRGB levels, 0–255) between each photo and the model rendered from its "
            "calibrated camera, over the pixels the model covers, after one exposure gain.</p>"
            + table(["photo", "RMS difference", "covered", "gain"], rows, {1, 2, 3}) + "".join(figs))


def _analyses(project: Project, rep: Report) -> None:
    """The analyses recorded in the project (FORMAT.md ``analyses``), each run again."""
    from vebuild.analysis.report_sections import analyses

    records = project.data.get("analyses") or []
    if records:
        rep.add("Analyses", analyses(project, rep, records))


def _hypotheses(project: Project, rep: Report) -> None:
    from vebuild.actions.hypothesis import label
    from vebuild.actions.render import RenderRequest, render_evidence

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


def digest(folder: Path) -> str:
    """SHA-256 over the report's HTML, images and figures (not the PDF, whose writer stamps it):
    the same project gives the same digest."""
    h = hashlib.sha256()
    for p in sorted([folder / "report.html", *(folder / "images").glob("*.png"), *(folder / "figures").glob("*")]):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()
