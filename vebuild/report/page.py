"""The report's page: its HTML pieces (escaping, numbers, tables), the :class:`Report` being
built (its sections, images and warnings), and the page assembled from them."""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from vebuild import __version__
from vebuild.project import Project
from vebuild.project.provenance import inputs_sha256

from .stale import banner_html

if TYPE_CHECKING:
    from vebuild.analysis.measure import CheckResult

#: Renders in the report are this wide (height from the view's aspect).

CSS = """
body { font-family: DejaVu Sans, Helvetica, Arial, sans-serif; font-size: 10.5pt; margin: 2em; color: #111; }
h1 { font-size: 18pt; } h2 { font-size: 14pt; border-bottom: 1px solid #999; margin-top: 1.6em; }
h3 { font-size: 11.5pt; }
table { border-collapse: collapse; margin: 0.5em 0 1em 0; }
td, th { border: 1px solid #bbb; padding: 2px 6px; text-align: left; vertical-align: top; overflow-wrap: break-word; }
th { background: #eee; } td.n { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
.nw { white-space: nowrap; } td.hash { font-family: DejaVu Sans Mono, monospace; font-size: 6pt; white-space: nowrap; }
table.wide { font-size: 8pt; } table.wide td, table.wide th { padding: 1px 4px; }
td.bad { color: #fff; background: #aa1414; font-weight: bold; white-space: nowrap; }
p.bad { color: #fff; background: #aa1414; font-weight: bold; padding: 2px 6px; }
td.good { white-space: nowrap; } td.entered { font-style: italic; white-space: nowrap; }
ul.lim { font-size: 9pt; margin-top: 0.2em; } ul.lim li { margin-bottom: 0.15em; }
.findings { page-break-after: always; } .findings h1 { font-size: 20pt; margin-top: 0.5em; }
table.case td:first-child, table.ident td:first-child { font-weight: bold; width: 12em; }
p.question { font-size: 12pt; border-left: 3px solid #555; padding-left: 0.6em; }
ol.answers li { margin-bottom: 0.4em; }
h1.annex { page-break-before: always; font-size: 16pt; }
dl.glossary dt { font-weight: bold; margin-top: 0.4em; } dl.glossary dd { margin-left: 1.5em; }
.declaration { white-space: pre-wrap; border: 1px solid #999; padding: 0.6em; margin-top: 1em; }
img { max-width: 100%; border: 1px solid #888; } img.plan { max-width: none; border: none; }
.hyp { color: #fff; background: #aa1414; padding: 2px 6px; font-weight: bold; }
.small { font-size: 9pt; color: #444; } pre.small { white-space: pre-wrap; font-size: 7.5pt; } .warn { color: #a05000; }
figure { margin: 0.5em 0 1.2em 0; page-break-inside: avoid; }
@page { size: A4; margin: 15mm; }
"""


@dataclass
class Report:
    folder: Path
    sections: list[str] = field(default_factory=list)
    images: list[Path] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: The reference and check distances measured on the final model (the checks and limitations show them).
    checks: list[CheckResult] = field(default_factory=list)
    #: Recorded analyses already run for this report (``$.analyses`` index → request and result), run once.
    recorded: dict[int, tuple[Any, Any]] = field(default_factory=dict)
    #: The paper the PDF is laid out for (CSS's name: "A4", "letter").
    paper: str = "A4"
    #: The first page (vebuild.report.findings), before every section.
    first: str = ""
    #: The index in ``sections`` where the annex (method and records) begins; None: no annex.
    annex_from: int | None = None

    def add(self, title: str, body: str) -> None:
        self.sections.append(f"<h2>{esc(title)}</h2>\n{body}")

    def image(self, name: str, pixels: np.ndarray, text: dict[str, str] | None = None) -> str:
        """Write an image into the report's folder; returns its relative path."""
        from vebuild.render.png import write_png

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


class Cell:
    """A table cell with a class of its own (``bad``: a failed check, ``entered``, ``hash``)."""

    def __init__(self, text: Any, cls: str) -> None:
        self.text, self.cls = text, cls


def _keep(text: str) -> str:
    """Escaped, a value and its σ ("1.23 ± 0.04") kept on one line."""
    return esc(text).replace(" ± ", "\u00a0±\u00a0")


def _cell(c: Any, numeric: bool) -> str:
    if isinstance(c, Cell):
        return f"<td class='{c.cls}'>{_keep(str(c.text))}</td>"
    text = str(c)
    if numeric and " / " in text:
        # Several numbers: each kept on one line, the cell breaking only between them.
        return "<td class='n' style='white-space: normal'>" + " / ".join(
            f"<span class='nw'>{esc(t)}</span>" for t in text.split(" / ")) + "</td>"
    return f"<td class='n'>{esc(text)}</td>" if numeric else f"<td>{_keep(text)}</td>"


def table(header: list[str], rows: list[list[Any]], numeric: set[int] | None = None, wide: bool = False) -> str:
    """An HTML table; the cells of the ``numeric`` columns are never broken inside a number (a
    cell of several numbers "a / b / c" breaks only between them); ``wide``: a smaller font."""
    numeric = numeric or set()
    opening = "<table class='wide'>" if wide else "<table>"
    out = [opening + "<tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>"]
    for r in rows:
        out.append("<tr>" + "".join(_cell(c, i in numeric) for i, c in enumerate(r)) + "</tr>")
    return "\n".join(out) + "</table>"


def still_words(photo: dict[str, Any]) -> str:
    """For a figure's caption: "; a still: frame 123 at 4.92 s of clip.mp4 (SHA-256 …), top field
    kept" where the photo is a still from video (FORMAT.md, "Stills from video"), else ""."""
    from vebuild.project.stills import origin_summary

    summary = origin_summary(photo)
    return "" if summary is None else f"; a still: {summary['words']}"


def identification(project: Project) -> str:
    """What identifies the work: the project, its file, the inputs digest (FORMAT.md, "Inputs
    digest"), the photos' count, vebuild's version and the command that reproduces the report."""
    data = project.data
    n_photos = len(data.get("photos", []))
    rows: list[list[Any]] = [
        ["project", data.get("name", project.path.name)], ["project file", project.path.name],
        ["inputs SHA-256", Cell(inputs_sha256(project.data), "hash")],
        ["photographs", f"{n_photos} (each listed with its SHA-256 under Photographs)"],
        ["software", f"vebuild {__version__}"],
        ["reproduce", f"vebuild report {project.path.name} --out DIR (the same project gives the same figures and "
                      "images)"]]
    cells = "".join(f"<tr><td>{esc(a)}</td>{_cell(b, False)}</tr>" for a, b in rows)
    return f"<table class='ident'>{cells}</table>"


def page(project: Project, rep: Report) -> str:
    """The whole page: the stale banner (if any), the first page, the warnings, the sections, and the
    annex under its heading, laid out for ``rep.paper``."""
    data = project.data
    head = [banner_html(project), rep.first]  # the banner with its <style>; "" for a current project
    if rep.warnings:
        head.append("<p class='warn'>" + "<br>".join(esc(w) for w in rep.warnings) + "</p>")
    body = list(rep.sections)
    if rep.annex_from is not None and rep.annex_from < len(body):
        body.insert(rep.annex_from, "<h1 class='annex'>Annex: the method, the calibration and the record of the "
                    "work</h1><p>What a second examiner needs to check and reproduce the figures above. The "
                    "glossary at its end explains the technical terms.</p>")
    css = CSS.replace("size: A4;", f"size: {rep.paper};")
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>vebuild report: {esc(data.get('name', ''))}</title><style>{css}</style></head><body>\n"
            + "\n".join(h for h in head if h) + "\n" + "\n".join(body) + "\n</body></html>\n")
