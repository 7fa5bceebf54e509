"""The report's page: its HTML pieces (escaping, numbers, tables), the :class:`Report` being
built (its sections, images and warnings), and the page assembled from them."""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vebuild import __version__
from vebuild.project import Project, sha256_file

from .stale import banner_html

#: Renders in the report are this wide (height from the view's aspect).

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


def table(header: list[str], rows: list[list[Any]], numeric: set[int] | None = None) -> str:
    numeric = numeric or set()
    out = ["<table><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>"]
    for r in rows:
        out.append("<tr>" + "".join(f"<td class='n'>{esc(c)}</td>" if i in numeric else f"<td>{esc(c)}</td>"
                                    for i, c in enumerate(r)) + "</tr>")
    return "\n".join(out) + "</table>"


def page(project: Project, rep: Report) -> str:
    data = project.data
    head = [f"<h1>vebuild report: {esc(data.get('name', project.path.name))}</h1>",
            table(["", ""], [["project file", project.path.name], ["project file SHA-256", sha256_file(project.path)],
                             ["software", f"vebuild {__version__}"],
                             ["reproduce", f"vebuild report {project.path.name} --out DIR (the same project gives "
                                           "the same figures and images)"]])]
    head.insert(0, banner_html(project))  # with its <style>; "" for a current project (vebuild.report.stale)
    if rep.warnings:
        head.append("<p class='warn'>" + "<br>".join(esc(w) for w in rep.warnings) + "</p>")
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>vebuild report: {esc(data.get('name', ''))}</title><style>{CSS}</style></head><body>\n"
            + "\n".join(head + rep.sections) + "\n</body></html>\n")
