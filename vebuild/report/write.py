"""``vebuild report``: the report written whole or not at all, and its digest."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

from vebuild.errors import VebuildError
from vebuild.project import Project

from . import deviation, findings, person, sections, single_view, without_model
from .page import Report, page
from .processing import processing
from .without_model import has_model, not_calibrated

#: Where the annex begins in :func:`report_steps`' list.
ANNEX = "annex"
#: The paper sizes a report is laid out for (``--paper``): CSS's names.
PAPERS = ("A4", "letter")

Section = Callable[[Project, Report], None]


def report_steps(modelled: bool, summary: bool = False) -> list[tuple[str, Section]]:
    """The report's sections after its first page (:mod:`vebuild.report.findings`), in the order a
    reader in court needs them: the evidence (views, the photos as marked, the measurements), the
    checks and limitations; then, after :data:`ANNEX`, the method and the records. ``summary``: the
    briefing's few pages (the views and the limitations), no annex."""
    def pick(with_model: Section, without: Section) -> Section:
        return with_model if modelled else without

    body: list[tuple[str, Section]] = [
        ("views", pick(sections.views, without_model.views)),
        ("marked photos", sections.marked_photos), ("measurements on the photos", single_view.section),
        ("person heights", person.section), ("analyses", sections.analyses),
        ("checks", pick(sections.checks, without_model.checks)),
        ("limitations", sections.limitations), ("hypotheses", pick(sections.hypotheses, without_model.hypotheses)),
        ("declaration", sections.declaration)]
    if summary:
        return [(n, f) for n, f in body if n in ("views", "person heights", "limitations", "declaration")]
    annex: list[tuple[str, Section]] = [
        ("identification", sections.identification), ("photos", sections.photos),
        ("calibration", sections.calibration),
        ("final cameras", pick(sections.final_cameras, without_model.final_cameras)),
        ("model", pick(sections.model, without_model.model)),
        ("validation", pick(sections.validation, without_model.validation)),
        ("laser scans", pick(deviation.scans, without_model.scans)), ("processing", processing),
        ("glossary", sections.glossary)]
    return [*body, (ANNEX, lambda project, rep: None), *annex]


#: The steps :func:`write_report` reports to its ``progress`` at most (the first page one, the PDF one more).
SECTIONS = len(report_steps(True))


def write_report(project: Project, out: Path, pdf: bool = True,
                 progress: Callable[[str], None] | None = None, *, summary: bool = False,
                 paper: str = "A4") -> Path:
    """Write ``out/report.html`` (and ``out/report.pdf``) with its images in ``out/images``: of a
    project with calibrated photos, modelled or not (without a model, the sections that need one
    are left out, each with a line saying why: :mod:`vebuild.report.without_model`). ``summary``:
    the first page, the evidence views and the limitations only (a briefing's few pages);
    ``paper``: one of :data:`PAPERS`."""
    from vebuild.project.atomic import MANIFEST, remove_tree, replace_folder, temp_path, write_text
    from vebuild.project.outputs import SOFTWARE, begin_stage, check_folder, write_manifest

    if paper not in PAPERS:
        raise VebuildError(f"--paper {paper}: expected one of {', '.join(PAPERS)}")
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
        rep = Report(tmp, paper=paper)
        step = progress or (lambda what: None)
        step("findings")
        rep.checks = sections.final_checks(project)
        findings.run_analyses(project, rep)
        rep.first = findings.findings(project, rep)
        for name, fn in report_steps(has_model(project), summary):
            if name == ANNEX:
                rep.annex_from = len(rep.sections)
                continue
            step(name)
            fn(project, rep)
        write_text(tmp / "report.html", page(project, rep))
        if pdf:
            step("pdf")
            write_pdf(tmp)
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


def write_pdf(folder: Path) -> None:
    """``folder/report.pdf`` from ``folder/report.html`` and its images (weasyprint)."""
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
