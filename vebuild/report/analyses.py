"""The report's section for the analyses a project records (FORMAT.md, ``analyses``).

Each record is a name and the words of a ``vebuild analyse`` command; the report parses them into
the typed request they describe (:func:`vebuild.analysis.recorded.parse_recorded`), runs it on the
project with its image written into the report's folder, and shows its table, its image and its
figures, so that the report shows what the project file gives now, and the command line that
reproduces each result.
"""

from __future__ import annotations

import json
import shlex
from typing import TYPE_CHECKING, Any

from vebuild.project.atomic import write_text

from .page import Report, esc

if TYPE_CHECKING:
    from vebuild.project import Project


#: The width a line of the page's text may take on the narrower paper (A4: 595 pt less the 15 mm page
#: margins and the body's 2 em margins), in points; and a monospaced character's width in ems
#: (DejaVu Sans Mono).
TEXT_WIDTH_PT, MONO_EM = 468.0, 0.602
#: The analyses' tables are set at 7.5 pt, smaller where their longest line would not fit, never below 4.5 pt.
PRE_PT, PRE_MIN_PT = 7.5, 4.5


def pre_points(text: str) -> float:
    """The type size (points) at which ``text``'s longest line fits the page's width, so that no
    number is cut at the margin or wrapped (at the least size a longer line wraps between words)."""
    longest = max((len(line) for line in text.splitlines()), default=1)
    return max(PRE_MIN_PT, min(PRE_PT, TEXT_WIDTH_PT / (MONO_EM * max(longest, 1))))


def analyses_html(project: Project, rep: Report, records: list[dict[str, Any]]) -> str:
    from vebuild.analysis.recorded import run_recorded
    from vebuild.analysis.single_view import SINGLE_VIEW_CLICKS
    from vebuild.project.units import RELATIVE_UNITS, length_unit

    lengths = f"in {RELATIVE_UNITS} (no scale was given)" if length_unit(project.data).relative else "in metres"
    parts = ["<p>Each analysis the project records, run again for this report; the command line reproduces it "
             f"(`--json OUT` writes its figures). Lengths {lengths}; intervals at 95 %.</p>"]
    (rep.folder / "figures").mkdir(exist_ok=True)
    for i, rec in enumerate(records):
        words = list(rec["command"])
        image = f"images/analysis-{i + 1}.png"
        request, result = rep.recorded.get(i) or run_recorded(project, i, rec, str(rep.folder / image))
        figures = {k: v for k, v in result.figures.items() if not str(k).endswith("_png")}  # paths of this run
        fig_name = f"figures/analysis-{i + 1}.json"
        write_text(rep.folder / fig_name, json.dumps({"analysis": request.name, "command": words, **figures},
                                                     indent=2, sort_keys=True, allow_nan=False) + "\n")
        text = result.table.replace(str(rep.folder) + "/", "")
        parts.append(f"<h3>{esc(rec['name'])}</h3>")
        if rec.get("description"):
            parts.append(f"<p>{esc(rec['description'])}</p>")
        command = "vebuild analyse " + shlex.quote(project.path.name) + " " + " ".join(shlex.quote(w) for w in words)
        parts.append(f"<p class='small'>{esc(command)} &nbsp; (figures: <a href='{fig_name}'>{fig_name}</a>)</p>")
        parts.append(f"<pre class='small' style='font-size: {pre_points(text):.2f}pt'>{esc(text)}</pre>")
        if words and words[0] in SINGLE_VIEW_CLICKS:  # drawn by vebuild.report.single_view
            parts.append("<p class='small'>Drawn on its photo under “Measurements on the photos”.</p>")
        if words[:1] == ["person-height"]:  # drawn and combined by vebuild.report.person
            parts.append("<p class='small'>Drawn on its photo and combined per person under “Person heights”.</p>")
        if result.image is not None and result.image.is_file():
            rep.images.append(result.image)
            parts.append(f"<figure><img src='{image}'></figure>")
    return "".join(parts)
