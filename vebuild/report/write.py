"""``vebuild report``: the report written whole or not at all, and its digest."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

from vebuild.errors import VebuildError
from vebuild.project import Project

from . import deviation, person, sections, single_view, without_model
from .page import Report, page
from .processing import processing
from .without_model import has_model, not_calibrated

#: The steps :func:`write_report` reports to its ``progress`` (the PDF one more).
SECTIONS = 16


def write_report(project: Project, out: Path, pdf: bool = True,
                 progress: Callable[[str], None] | None = None) -> Path:
    """Write ``out/report.html`` (and ``out/report.pdf``) with its images in ``out/images``: of a
    project with calibrated photos, modelled or not (without a model, the sections that need one
    are left out, each with a line saying why: :mod:`vebuild.report.without_model`)."""
    from vebuild.project.atomic import MANIFEST, remove_tree, replace_folder, temp_path, write_text
    from vebuild.project.outputs import SOFTWARE, begin_stage, check_folder, write_manifest

    given = Path(out)
    if not given.parent.is_dir():
        raise VebuildError(f"{given}: the folder {given.parent} does not exist; create it first")
    check_folder(project, given, "report")
    if not (project.data.get("calibration") or {}).get("cameras"):
        raise VebuildError(not_calibrated(project))
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
        rep.checks = sections.final_checks(project)
        modelled = has_model(project)
        steps = [("photos", sections.photos), ("calibration", sections.calibration),
                 ("final cameras", sections.final_cameras if modelled else without_model.final_cameras),
                 ("model", sections.model if modelled else without_model.model),
                 ("checks", sections.checks if modelled else without_model.checks),
                 ("limitations", sections.limitations), ("plan", sections.plan if modelled else without_model.plan),
                 ("views", sections.views if modelled else without_model.views),
                 ("marked photos", sections.marked_photos), ("measurements on the photos", single_view.section),
                 ("person heights", person.section),
                 ("validation", sections.validation if modelled else without_model.validation),
                 ("laser scans", deviation.scans if modelled else without_model.scans),
                 ("analyses", sections.analyses),
                 ("hypotheses", sections.hypotheses if modelled else without_model.hypotheses),
                 ("processing", processing)]
        for name, fn in steps:
            step(name)
            fn(project, rep)
        write_text(tmp / "report.html", page(project, rep))
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
    from weasyprint.urls import URLFetcher

    class _InsideTheReport(URLFetcher):
        """Reads the page's images from the report's own folder, by their relative names."""

        def fetch(self, url: str, headers: dict[str, str] | None = None) -> object:
            if url.startswith("data:"):
                return super().fetch(url, headers)
            path = (folder / url).resolve()
            if folder.resolve() not in path.parents:
                raise ValueError(f"{url}: not a file of the report")
            return super().fetch(path.as_uri(), headers)

    # The page's relative names are kept as they are: a base URL of no hierarchical scheme joins
    # nothing, so links stay relative to the PDF (figures/analysis-1.json beside it) and images are
    # named by their relative names. The folder the report is built in (a temporary one beside the
    # output) appears nowhere in the PDF, and two examiners' PDFs are the same bytes.
    html = (folder / "report.html").read_text(encoding="utf-8")
    doc = weasyprint.HTML(string=html, base_url="report:", url_fetcher=_InsideTheReport())
    doc.write_pdf(folder / "report.pdf", metadata=None, uncompressed_pdf=False)


def digest(folder: Path) -> str:
    """SHA-256 over the report's HTML, images (PNG and the plan's SVG) and figures (not the PDF, whose
    writer stamps it): the same project gives the same digest."""
    h = hashlib.sha256()
    images = [*(folder / "images").glob("*.png"), *(folder / "images").glob("*.svg")]
    for p in sorted([folder / "report.html", *images, *(folder / "figures").glob("*")]):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()
