"""`vebuild report` of calibrated photos with no model: one generated archived photo, calibrated
alone, two single-view measurements saved as the project's analyses, reported; what is in it, that
its figures are `vebuild analyse`'s for the same words, and that each measurement is drawn on the
photo where it was clicked."""

from __future__ import annotations

import html
import json
import re
from typing import Any

import numpy as np
import pytest
from one_photo_scene import W, one_photo, write_one_photo

from vebuild.analysis.single_view import single_view_command
from vebuild.cli import main
from vebuild.project import load_project, save_project
from vebuild.project.provenance import command_context
from vebuild.render.sizes import IMAGE_WIDTH
from vebuild.report.marked_photos import marked_photo
from vebuild.report.single_view import MEASURED_RGB, REFERENCE_RGB, Drawn, drawn_photo
from vebuild.report.without_model import NO_MODEL
from vebuild.report.write import digest, write_report

#: A line across a vanishing point's segments, far off it: the robust fit leaves it out.
CLUTTER_Z = [300.0, 900.0, 420.0, 400.0]
CASE = {"number": "2026/0046", "examiner": "A. N. Examiner"}
#: Report pixels per photo pixel.
SCALE = IMAGE_WIDTH / W


def _section(page: str, title: str) -> str:
    """The HTML of the section titled ``title``, up to the next section."""
    start = page.index(f"<h2>{title}</h2>")
    end = page.find("<h2>", start + 1)
    return page[start:end if end > 0 else len(page)]


def _cli(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def one_photo_report(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("one-photo")
    ph = one_photo(np.random.default_rng(41))
    path = write_one_photo(folder, ph, floor_distance=True)
    project = load_project(path)
    project.data["photos"][0]["vanishing_segments"]["z"].append(CLUTTER_Z)
    save_project(project)
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["case", str(path), "--number", CASE["number"], "--examiner", CASE["examiner"]]) == 0
    c = ph.clicks
    project = load_project(path)
    project.data["analyses"] = [
        {"name": "box height", "description": "the box's top above the floor",
         "command": single_view_command("photo-height", "p", [c["box_foot"], c["box_top"]])},
        {"name": "F1 to F3", "command": single_view_command("floor-distance", "p", [c["F1"], c["F3"]])}]
    with command_context("edit", [str(path)], [str(path)]):  # saved as the modelling screen saves them
        save_project(project)
    out = folder / "report"
    assert main(["report", str(path), "--out", str(out), "--quiet"]) == 0
    return {"path": path, "out": out, "page": (out / "report.html").read_text(), "photo": ph}


def test_the_report_of_one_photo_has_its_sections_and_leaves_out_the_model_s(one_photo_report):
    page, path = one_photo_report["page"], one_photo_report["path"]
    project = load_project(path)
    for title in ("Photographs", "Calibration (vanishing points)", "Reference and check distances", "Limitations",
                  "The photos as marked", "Measurements on the photos", "Analyses", "Processing record"):
        assert f"<h2>{title}</h2>" in page, title
    title = page[page.index("<div class='findings'>"):page.index("<h2>")]
    assert all(v in title for v in CASE.values())
    assert project.data["photos"][0]["sha256"] in page
    # Each section that needs a model: one line saying why, no table, no image.
    for title in ("Final cameras", "Model", "Plan", "Evidence views", "How well the model explains each photo"):
        body = _section(page, title)
        assert html.escape(NO_MODEL) in body, title
        assert "<table" not in body and "<img" not in body and body.count("<p") == 1, title
    # The calibration and its checks: mode, f, principal point, lens, rotation and position ± 1σ; the
    # photo's origin, scale source and camera height ± 1σ; the lines used and the one left out.
    cam = project.data["calibration"]["cameras"]["p"]
    cal = html.unescape(_section(page, "Calibration (vanishing points)")).replace("\u00a0", " ")
    f, pp = cam["focal_px"], cam["principal_point"]["value"]
    assert f"{f['value']:.1f} ± {f['sigma']:.1f}" in cal and f"({pp[0]:.1f}, {pp[1]:.1f})" in cal
    assert "pinhole" in cal and "p: 3vp: " in cal
    pitch = cam["ypr_deg"]
    assert f"{pitch['value'][1]:.2f} ± {pitch['sigma'][1]:.2f}" in cal
    h = cam["placement"]["camera_height_m"]
    assert f"{h['value']:.3f} ± {h['sigma']:.3f} m" in cal and cam["placement"]["scale"] in cal
    rejected = cam["vanishing_points"]["z"]["rejected"]
    assert [r["segment"] for r in rejected] == [5]  # the clutter line, left out
    assert re.search(r"<td>p</td><td>z</td><td class='n'>6</td><td class='n'>5</td><td>5: off its vanishing point",
                     _section(page, "Calibration (vanishing points)"))
    # The scale distance as the calibration measured it, with its verdict.
    ref = project.data["calibration"]["reference_distances"][0]
    checks = _section(page, "Reference and check distances")
    assert f"{ref['measured']:.4f}" in checks and "within" in checks
    # What one photo cannot tell, in words.
    lim = _section(page, "Limitations")
    assert "What a single photo cannot tell" in lim and "flat, level" in lim and "its foot" in lim
    assert "no lens distortion was estimated" in lim
    # The audit trail of the commands that made the project.
    assert "vebuild calibrate" in page and "The chain verifies" in page


def test_the_report_s_figures_are_those_vebuild_analyse_gives_for_the_same_words(one_photo_report, tmp_path,
                                                                                   capsys):
    path, out, page = one_photo_report["path"], one_photo_report["out"], one_photo_report["page"]
    table = _section(page, "Measurements on the photos")
    analyses = html.unescape(_section(page, "Analyses"))
    for k, rec in enumerate(load_project(path).data["analyses"], start=1):
        js = tmp_path / f"{k}.json"
        code, stdout, err = _cli(capsys, "analyse", str(path), *rec["command"], "--json", str(js))
        assert code == 0, err
        said = json.loads(js.read_text())
        shown = json.loads((out / "figures" / f"analysis-{k}.json").read_text())
        assert shown["command"] == rec["command"]
        assert shown["measurements"] == said["measurements"] and shown["photo"] == said["photo"] == "p"
        # The table the command prints, line for line in the report.
        lines = [line for line in stdout.splitlines() if line.strip() and not line.startswith("figures written")]
        assert len(lines) == 3
        for line in lines:
            assert line in analyses, line
        (m,) = said["measurements"]
        lo, hi = m["ci95_m"]
        row = (f"<td class='n'>{m['value_m']:.4f}</td><td class='n'>{1000 * m['sigma_m']:.2f}</td>"
               f"<td class='n'>{lo:.4f} – {hi:.4f}</td>")
        assert row in table
    assert table.count("<img src='images/measured-1.png'>") == 1


def test_each_measurement_is_drawn_on_the_photo_where_it_was_clicked(one_photo_report):
    from PIL import Image

    out, ph = one_photo_report["out"], one_photo_report["photo"]
    img = np.asarray(Image.open(out / "images" / "measured-1.png").convert("RGB"))
    assert img.shape[1] == IMAGE_WIDTH
    plain = np.asarray(Image.open(out / "images" / "marks-1.png").convert("RGB"))
    c = ph.clicks
    for a, b in (("box_foot", "box_top"), ("F1", "F3")):
        for t in np.linspace(0.15, 0.85, 8):
            u, v = (1 - t) * c[a] + t * c[b]
            x, y = round(u * SCALE - 0.5), round(v * SCALE - 0.5)
            assert tuple(img[y, x]) == MEASURED_RGB, (a, b, t)
            assert tuple(plain[y, x]) != MEASURED_RGB  # drawn for the measurement, not there before
    # Nowhere else: no measured colour mirrored across the photo from a clicked line.
    u, v = 0.5 * (c["box_foot"] + c["box_top"])
    assert tuple(img[round(v * SCALE), round((W - u) * SCALE)]) != MEASURED_RGB


def test_a_length_on_a_wall_is_drawn_with_its_reference_clicks(one_photo_report):
    project = load_project(one_photo_report["path"])
    clicks = ((400.0, 900.0), (1200.0, 850.0), (600.0, 500.0), (1000.0, 450.0))
    d = Drawn(1, 0, "shelf", "wall-length", "p", clicks, {"value_m": 1.2, "sigma_m": 0.01, "ci95_m": [1.18, 1.22]})
    img = drawn_photo(project, 0, [d])
    x, y = round(800 * SCALE - 0.5), round(475 * SCALE - 0.5)  # the length's middle
    assert tuple(img[y, x]) == MEASURED_RGB
    x, y = round(800 * SCALE - 0.5), round(875 * SCALE - 0.5)  # the wall's foot line, a reference
    assert tuple(img[y, x]) == REFERENCE_RGB
    assert d.label() == "1: 1.200 m, 95 %: [1.180, 1.220]"


def test_the_photo_as_marked_shows_its_known_length_and_the_line_left_out(one_photo_report):
    project = load_project(one_photo_report["path"])
    _, counts = marked_photo(project, 0, IMAGE_WIDTH)
    z = project.data["photos"][0]["vanishing_segments"]["z"]
    assert counts["known_lengths"] == 1 and counts["rejected"] == 1 and counts["segments"] == 5 + 6 + 6
    assert len(z) == 6
    assert "1 vanishing segment left out by the calibration (grey, crossed), 1 known length (white)" in \
        one_photo_report["page"]


def test_the_pdf_pages_show_the_measurements_and_the_report_is_reproducible(one_photo_report, tmp_path):
    pdfium = pytest.importorskip("pypdfium2")
    out = one_photo_report["out"]
    pdf = pdfium.PdfDocument(str(out / "report.pdf"))
    # At 144 dpi the report's 960-pixel images are drawn about as wide as they are (the page's text
    # column is 180 mm, 1020 pixels).
    pages = [np.asarray(pdf[i].render(scale=2.0).to_pil().convert("RGB")) for i in range(len(pdf))]
    assert len(pages) >= 4

    def measured_colour(img: np.ndarray) -> int:  # resampling blurs the lines' edges: within 40 levels
        return int(np.sum(np.all(np.abs(img.astype(int) - MEASURED_RGB) <= 40, axis=2)))

    from PIL import Image

    drawn = measured_colour(np.asarray(Image.open(out / "images" / "measured-1.png").convert("RGB")))
    near = [measured_colour(p) for p in pages]
    assert sum(n > 0 for n in near) == 1  # the one photo with its measurements, on one page
    assert 0.5 * drawn < max(near) < 1.5 * drawn
    write_report(load_project(one_photo_report["path"]), tmp_path / "again", pdf=False)
    assert digest(tmp_path / "again") == digest(out)


def test_relative_lengths_are_said_so_in_the_measurements(tmp_path):
    ph = one_photo(np.random.default_rng(43))
    path = write_one_photo(tmp_path, ph, known_length=False)
    assert main(["calibrate", str(path), "--quiet"]) == 0
    project = load_project(path)
    c = ph.clicks
    project.data["analyses"] = [{"name": "box height", "command": single_view_command(
        "photo-height", "p", [c["box_foot"], c["box_top"]])}]
    save_project(project)
    write_report(load_project(path), tmp_path / "r", pdf=False)
    page = (tmp_path / "r" / "report.html").read_text()
    table = _section(page, "Measurements on the photos")
    assert "value rel." in table and "relative units: the camera height is 1" in table and "value m" not in table
    assert "no scale was given, so the photo gives only proportions" in _section(page, "Limitations")
    assert "1 (the unit of length)" in _section(page, "Calibration (vanishing points)")


def test_a_project_not_calibrated_is_refused_naming_what_to_do(tmp_path, capsys):
    ph = one_photo(np.random.default_rng(44))
    path = write_one_photo(tmp_path, ph)
    code, _, err = _cli(capsys, "report", str(path), "--out", str(tmp_path / "r"), "--quiet")
    assert code == 2 and "Traceback" not in err
    assert f"{path.name}: no report yet: the photos are not calibrated yet; run `vebuild calibrate {path.name}`" \
        in err and "a model is optional" in err
    project = load_project(path)
    project.data["photos"][0].pop("vanishing_segments")
    save_project(project)
    code, _, err = _cli(capsys, "report", str(path), "--out", str(tmp_path / "r"), "--quiet")
    assert code == 2 and f"Mark the lines of each photo (`vebuild detect {path.name}`" in err
    assert not (tmp_path / "r").exists()


def test_several_photos_each_placed_alone_are_each_drawn_with_their_measurements(tmp_path):
    from vebuild.synthetic import write_project

    a, b = one_photo(np.random.default_rng(65)), one_photo(np.random.default_rng(66))
    b.cam.id = "q"
    path = write_project(tmp_path, [a.cam, b.cam], {n: a.points[n] for n in ("O", "F1")})
    project = load_project(path)
    project.data["reference_distances"] = []
    project.data["markers"] = [{"name": "O"}]
    for p, ph in zip(project.data["photos"], (a, b), strict=True):
        p["marker_observations"] = {}
        p["camera_height"] = {"value": float(ph.C[2]), "sigma": 0.01}
    project.data["analyses"] = [{"name": f"box in {pid}", "command": single_view_command(
        "photo-height", pid, [ph.clicks["box_foot"], ph.clicks["box_top"]])} for pid, ph in (("p", a), ("q", b))]
    save_project(project)
    assert main(["calibrate", str(path), "--quiet"]) == 0
    write_report(load_project(path), tmp_path / "r", pdf=False)
    page = (tmp_path / "r" / "report.html").read_text()
    table = _section(page, "Measurements on the photos")
    from PIL import Image

    for k, (pid, ph) in enumerate((("p", a), ("q", b)), start=1):
        assert f"<td>box in {pid}</td><td>{pid}</td>" in table
        img = np.asarray(Image.open(tmp_path / "r" / "images" / f"measured-{k}.png").convert("RGB"))
        u, v = 0.5 * (ph.clicks["box_foot"] + ph.clicks["box_top"])
        assert tuple(img[round(v * SCALE - 0.5), round(u * SCALE - 0.5)]) == MEASURED_RGB
    rows = re.findall(r"<tr><td>([pq])</td><td>[^<]*</td><td>[^<]*</td><td class='n'>([0-9.]+) ± ([0-9.]+) m</td>",
                      _section(page, "Calibration (vanishing points)"))
    assert [r[0] for r in rows] == ["p", "q"]
    for (_, h, s), ph in zip(rows, (a, b), strict=True):
        assert abs(float(h) - ph.C[2]) <= 4 * 0.01 and float(s) > 0  # each camera height, its own scale


def test_a_measurement_that_no_longer_fits_its_photo_is_named(one_photo_report, tmp_path):
    from vebuild.errors import ProjectError

    project = load_project(one_photo_report["path"])
    project.data["analyses"][1]["command"] = single_view_command("floor-distance", "p", [(400.0, 5.0),
                                                                                         (500.0, 900.0)])
    with pytest.raises(ProjectError, match=r"\$\.analyses\[1\]\.command: photo 'p': the first point: pixel "
                       r"\(400\.0, 5\.0\) lies on or above the horizon"):
        write_report(project, tmp_path / "r", pdf=False)
    assert not (tmp_path / "r").exists()
