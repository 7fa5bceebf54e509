"""The report's stale banner: at the top of the HTML page, and on every page of the PDF (a CSS
``@page`` margin box, which weasyprint draws on each page), whenever a result of the project is
stale (:func:`vebuild.project.provenance.stale`). A current project gets neither. The banner carries
its own ``<style>`` (weasyprint reads style elements anywhere in the document), so that the page
adds it with one line."""

from __future__ import annotations

import html
import json

from vebuild.project import Project
from vebuild.project.provenance import TITLES, stale

#: The banner's look on the page; the PDF's margin box gets the same colours.
CSS = """
.stale-banner { border: 2px solid #b00000; background: #fff0f0; color: #800000; padding: 6px 10px;
                margin: 0 0 1em 0; font-weight: bold; }
.stale-banner ul { margin: 0.3em 0 0 1.2em; padding: 0; font-weight: normal; }
"""


def _short(project: Project) -> str:
    found = stale(project.data, project.path.name)
    if not found:
        return ""
    what = ", ".join(TITLES[s.stage].removeprefix("the ") for s in found)
    return f"STALE RESULTS ({what}): see “Processing record”"


def banner_html(project: Project) -> str:
    """The HTML banner naming each stale result, why and the command that updates it; "" if none."""
    found = stale(project.data, project.path.name)
    if not found:
        return ""
    items = "".join(f"<li>{html.escape(s.message)}</li>" for s in found)
    return (f"<style>{banner_css(project)}</style><div class='stale-banner'>These results are stale: the project "
            f"changed after they were computed. The figures below are the old results.<ul>{items}</ul></div>")


def banner_css(project: Project) -> str:
    """The banner's CSS, with the PDF's margin box on every page when the project has a stale result."""
    short = _short(project)
    if not short:
        return ""
    # json.dumps gives a quoted string whose escapes CSS reads alike (\\" and \\\\); no newline is in it.
    box = ("content: " + json.dumps(short, ensure_ascii=False) + "; color: #800000; font-family: DejaVu Sans, "
           "Helvetica, Arial, sans-serif; font-weight: bold; font-size: 9pt; border-bottom: 1.5pt solid #b00000;")
    return CSS + "@page { @top-center { " + box + " } }\n"
