"""The report for the reader in court, on the example room solved and textured, with recorded
analyses and the case's question: page 1 states the case, the question, each answer with its
interval in words and a scaled plan; the evidence follows; the method and the records are an annex
ending in a glossary; no number in any table is cut at the margin or wrapped, at A4 and at Letter
(read from the PDF's text positions); ``--summary`` is a briefing of at most four pages.

One report is written per module (it renders: tens of seconds); the tests read it."""

from __future__ import annotations

import json
import re
import shutil
from html import unescape
from html.parser import HTMLParser

import pytest

from vebuild.cli import main
from vebuild.report.glossary import GLOSSARY
from vebuild.report.write import write_pdf

pdfium = pytest.importorskip("pypdfium2")

QUESTION = "How far is the cabinet from the table, and could a witness in the doorway see the box?"
#: The page's margins (15 mm, page.py's CSS) in points: no character's box may reach past them.
MARGIN_PT = 15 / 25.4 * 72
#: A glyph's box may overhang the text column by a hair (its side bearing), in points.
OVERHANG_PT = 1.0


@pytest.fixture(scope="module")
def reader(textured_room, tmp_path_factory):
    """(report folder, report.html text) of the example with analyses and case details."""
    folder = tmp_path_factory.mktemp("reader") / "room"
    shutil.copytree(textured_room.parent, folder)
    proj = folder / textured_room.name
    data = json.loads(proj.read_text())
    data["analyses"] = [
        {"name": "cabinet to table", "command": ["distance", "cabinet:v4", "table.top:v6"]},
        {"name": "table height", "command": ["height", "table.top:v6"]},
        {"name": "check distances", "command": ["checks"]},
        {"name": "the box from the doorway", "command": ["sightline", "--standing", "3.7,0.4", "--object", "box"]},
    ]
    proj.write_text(json.dumps(data, indent=1))
    assert main(["case", str(proj), "--number", "2026/0042", "--examiner", "A. Examiner", "--question",
                 QUESTION]) == 0
    out = folder.parent / "report"
    assert main(["report", str(proj), "--out", str(out), "--quiet"]) == 0
    return proj, out, (out / "report.html").read_text()


def _pdf_lines(path) -> list[tuple[int, str, list[tuple[float, float, float, float]], float]]:
    """Every line of text on every page: (page, text, its characters' boxes, the page's width)."""
    pdf = pdfium.PdfDocument(str(path))
    out = []
    for i in range(len(pdf)):
        page = pdf[i]
        width, _ = page.get_size()
        tp = page.get_textpage()
        text = tp.get_text_range()
        boxes = [tp.get_charbox(k) for k in range(tp.count_chars())]
        k = 0
        for line in text.split("\r\n"):
            out.append((i, line, boxes[k:k + len(line)], width))
            k += len(line) + 2  # the line break is two characters of the text page
    return out


class _Cells(HTMLParser):
    """The text of every table cell and preformatted block of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.cells: list[str] = []
        self._open = 0

    def handle_starttag(self, tag, attrs):
        if tag in ("td", "th", "pre"):
            self._open += 1
            self.cells.append("")

    def handle_endtag(self, tag):
        if tag in ("td", "th", "pre"):
            self._open -= 1

    def handle_data(self, data):
        if self._open:
            self.cells[-1] += data


NUMBER = re.compile(r"[−+-]?\d+(?:[.,]\d+)*")


def test_page_one_states_the_case_the_question_the_answers_and_the_plan(reader):
    proj, out, page = reader
    first = page[:page.index("</div>", page.index("class='findings'"))]
    assert "2026/0042" in first and "A. Examiner" in first and QUESTION in first
    answers = [unescape(a) for a in re.findall(r"<li>(.*?)</li>", first[first.index("The answers"):])]
    assert len(answers) == 4 + 1 - 1  # one per measurement (distance, height), the checks' rows, the sight line
    distance = json.loads((out / "figures" / "analysis-1.json").read_text())["measurements"][0]
    lo, hi = distance["ci95_m"]
    assert (f"cabinet to table: distance cabinet:v4 to table.top:v6: {distance['value_m']:.3f} m, between "
            f"{lo:.3f} and {hi:.3f} m (95 %; 1σ {1000 * distance['sigma_m']:.1f} mm).") == answers[0]
    sight = json.loads((out / "figures" / "analysis-4.json").read_text())["sightline"]
    assert f"{100 * sight['visible_share']:.0f} % of the object's surface facing the eye can be seen" in answers[3]
    assert "measured at the scene and not used to build the model: " in first
    assert "<img class='plan' src='images/plan.svg'>" in first and "1 : " in first
    # In the PDF, all of it on the first page: the last answer and the plan's caption.
    lines = _pdf_lines(out / "report.pdf")
    on_first = " ".join(t for p, t, _, _ in lines if p == 0)
    assert "The question" in on_first and "The answers" in on_first and "The scene from above" in on_first
    assert "can be seen" in on_first


def test_the_evidence_first_the_method_in_an_annex_with_a_glossary(reader):
    _, _, page = reader
    heads = re.findall(r"<h([12])[^>]*>([^<]*)</h\1>", page)
    titles = [t for _, t in heads]
    annex = next(i for i, (level, t) in enumerate(heads) if t.startswith("Annex"))
    body, after = titles[:annex], titles[annex:]
    for t in ("Evidence views", "The photos as marked", "Analyses", "Reference and check distances", "Limitations"):
        assert t in body, t
    for t in ("Identification", "Photographs", "Calibration (vanishing points)", "Model", "Processing record",
              "Glossary"):
        assert t in after, t
    assert after[-1] == "Glossary"
    assert body.index("Evidence views") < body.index("Analyses") < body.index("Limitations")
    glossary = page[page.index(">Glossary<"):]
    for term in ("1σ", "vanishing point", "lens distortion"):
        assert f"<dt>{term}" in glossary
    assert len(GLOSSARY) == glossary.count("<dt>")
    # The jargon stays in the annex: the body before it says none of it.
    before = page[:page.index("class='annex'")]
    for word in ("3vp", "1vp", "paper §", "k1"):
        assert word not in before, word


@pytest.mark.parametrize("paper", ["A4", "letter"])
def test_no_number_in_a_table_is_cut_or_wrapped(reader, paper, tmp_path):
    _, out, page = reader
    folder = tmp_path / "r"
    shutil.copytree(out, folder)
    html = page.replace("size: A4;", f"size: {paper};")
    assert html != page or paper == "A4"
    (folder / "report.html").write_text(html)
    write_pdf(folder)
    lines = _pdf_lines(folder / "report.pdf")
    # Nothing past the right margin (a cut table shows its cells there, or off the page).
    for p, text, boxes, width in lines:
        for (left, _, right, _), ch in zip(boxes, text, strict=True):  # (left, bottom, right, top)
            if ch.strip():
                assert MARGIN_PT - OVERHANG_PT <= left and right <= width - MARGIN_PT + OVERHANG_PT, (paper, p, text)
    # Every number of every table cell and analysis table whole on one line of the PDF.
    parser = _Cells()
    parser.feed(page)
    numbers = {n for cell in parser.cells for n in NUMBER.findall(cell) if len(n.lstrip("−+-")) >= 3}
    assert len(numbers) > 200
    words = {w for _, text, _, _ in lines for w in NUMBER.findall(text)}
    missing = sorted(n for n in numbers if n not in words and n.lstrip("−+-") not in words)
    assert not missing, (paper, missing[:20])


def test_a_summary_of_at_most_four_pages(reader, tmp_path):
    proj, _, _ = reader
    out = tmp_path / "brief"
    assert main(["report", str(proj), "--out", str(out), "--quiet", "--summary"]) == 0
    page = (out / "report.html").read_text()
    assert QUESTION in page and ">Evidence views<" in page and ">Limitations<" in page
    assert "class='annex'" not in page and ">Photographs<" not in page
    pdf = pdfium.PdfDocument(str(out / "report.pdf"))
    assert 1 <= len(pdf) <= 4
