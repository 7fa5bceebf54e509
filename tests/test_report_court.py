"""The report for a court, on the example room re-calibrated: one stage's figures at a time, check
distances from the final model with their verdicts, entered values marked, the limitations made
from the project, the case details on the title page, the plan view and the photos as marked.

One report is generated per module (it renders: tens of seconds); the tests read it."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from vebuild.analysis.measure import check_distances
from vebuild.analysis.solved import SolvedModel
from vebuild.cli import main
from vebuild.project import Project, load_project, sha256_file
from vebuild.project.provenance import inputs_sha256
from vebuild.report.findings import PLAN_HEIGHT_MM
from vebuild.report.limitations import entered_values, limitations
from vebuild.report.marked_photos import marked_photo
from vebuild.report.plan import plan_svg
from vebuild.report.write import digest, write_report

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
#: The check distance on model vertices: the box's top corner to the table top's, its known value
#: the ground truth's (a tape's 1σ, 2 mm, as the format's default).
VERTEX_CHECK = ("box:v4", "table.top:v6")
CASE = {"number": "2026/0417-B", "examiner": "A. N. Examiner", "organisation": "Forensic Imaging Unit",
        "photo_dates": "2026-11-20, 14:05-14:40", "declaration": "I declare that this report is true."}


#: The tests that share `court` run in one pytest-xdist worker (`--dist loadgroup`, pyproject's
#: addopts), so that it is computed once, not once per worker.
SHARES_COURT = pytest.mark.xdist_group("report_court.court")


@pytest.fixture(scope="module")
def court(tmp_path_factory):
    """(project file, report folder, report.html text) of the example calibrated, solved with
    re-calibration, textured (60 texels per metre), with case details and a check distance on
    model vertices."""
    folder = tmp_path_factory.mktemp("court") / "room"
    shutil.copytree(ROOM, folder, ignore=shutil.ignore_patterns("textures"))
    proj = folder / "room.vebuild.json"
    truth = json.loads((ROOM / "ground_truth.json").read_text())["model_handles"]
    ends = [np.asarray(truth[n][h]) for n, h in (e.split(":") for e in VERTEX_CHECK)]
    data = json.loads(proj.read_text())
    data["reference_distances"].append({"a": VERTEX_CHECK[0], "b": VERTEX_CHECK[1], "role": "check",
                                        "distance": round(float(np.linalg.norm(ends[0] - ends[1])), 4)})
    proj.write_text(json.dumps(data, indent=1))
    assert main(["calibrate", str(proj), "--quiet"]) == 0  # the check on vertices waits for the solve
    assert main(["solve", str(proj), "--recalibrate"]) == 0
    data = json.loads(proj.read_text())
    assert data["model_solution"]["cameras"], "the solve re-calibrated no camera"
    assert not any(c.get("recalibrated") for c in data["calibration"]["cameras"].values())
    assert main(["texture", str(proj), "--quiet", "--density", "60"]) == 0
    words = ["case", str(proj)]
    for key, value in CASE.items():
        words += ["--" + key.replace("_", "-"), value]
    assert main(words) == 0
    out = folder.parent / "report"
    write_report(load_project(proj), out, pdf=False)
    return proj, out, (out / "report.html").read_text()


def _row(page: str, first: str) -> str:
    """The table row whose first cell is ``first``, as text."""
    m = re.search(r"<tr><td>" + re.escape(first) + r"</td>.*?</tr>", page)
    assert m, f"no row {first!r}"
    return m.group(0)


@SHARES_COURT
def test_check_distances_are_the_final_models_with_a_verdict(court):
    proj, _, page = court
    project = load_project(proj)
    final = {(c.a, c.b): c for c in check_distances(project, SolvedModel.from_project(project))}
    t2c1 = final[("T2", "C1")]
    assert t2c1.measured.source == "model solution"
    # The example's check distance lies outside the final model's 95 % interval: the verdict says so.
    assert not t2c1.within_ci95 and t2c1.verdict == "outside the 95 % interval"
    row = _row(page, "T2 – C1")
    assert f"{1000 * t2c1.difference:+.1f}" in row and "OUTSIDE" in row
    lo, hi = t2c1.difference_ci95
    assert f"{1000 * lo:+.1f} … {1000 * hi:+.1f}" in row
    # The calibration stage's value is shown beside, labelled, and is not the final one.
    stage = next(d for d in project.data["calibration"]["reference_distances"] if d["a"] == "T2")
    assert f"{1000 * (stage['measured'] - stage['distance']):+.1f}" in row and "calibration stage mm" in page
    assert round(1000 * (stage["measured"] - stage["distance"]), 1) != round(1000 * t2c1.difference, 1)
    assert "T2 – C1: difference" in page  # listed among the limitations too
    # A check distance ending on model vertices, measured on the final model.
    vertex = final[VERTEX_CHECK]
    assert vertex.measured.nodes and vertex.measured.source == "model solution"
    row = _row(page, " – ".join(VERTEX_CHECK))
    assert f"{vertex.measured.value:.4f}" in row and ("OUTSIDE" if not vertex.within_ci95 else "within") in row
    assert vertex.to_json()["verdict"] == vertex.verdict
    # The scale distances measured the same way, labelled as such (the solve fitted them: no check).
    scale = check_distances(project, SolvedModel.from_project(project), roles=("scale",))
    assert [(c.a, c.b, c.role) for c in scale] == [("O", "X5", "scale"), ("O", "Y4", "scale")]
    assert all(f"{c.measured.value:.4f}" in _row(page, f"{c.a} – {c.b}") for c in scale)


@SHARES_COURT
def test_each_stage_labelled_and_entered_values_marked(court):
    proj, _, page = court
    data = load_project(proj).data
    calibration = page[page.index(">Calibration (vanishing points)<"):page.index(">Final cameras")]
    final = page[page.index(">Final cameras (re-calibrated with the model)<"):page.index(">Model<")]
    for pid, c in data["calibration"]["cameras"].items():
        assert not c.get("recalibrated")
        assert f">{c['focal_px']['value']:.1f} ± " in calibration  # a numeric cell: never broken
        assert c["mode"] in calibration and c["mode_reason"][:40] in calibration
        r = data["model_solution"]["cameras"][pid]
        assert f">{r['focal_px']['value']:.1f} ± {r['focal_px']['sigma']:.1f}<" in final
    # No entered value reads as a perfect measurement.
    model = page[page.index(">Model<"):page.index(">How well the model explains each photo<")]
    assert "± 0.0000" not in model and "4.0000 – 4.0000" not in model and "0.7200 – 0.7200" not in model
    leg = re.findall(r"<tr><td>table\.leg1</td><td>height</td>.*?</tr>", model)
    assert len(leg) == 1 and "entered" in leg[0] and "taken as exact" in leg[0]
    wall = re.findall(r"<tr><td>wall_west</td><td>width</td>.*?</tr>", model)
    assert len(wall) == 1 and "entered" in wall[0]


def test_entered_values_from_hold_objects_and_the_solution():
    data = {"model": {"nodes": [
        {"name": "a", "primitive": {"type": "box", "params": {"width": 1, "depth": 1, "height": 1}},
         "hold": ["height", {"name": "width", "sigma": 0.002}]},
        {"name": "w", "primitive": {"type": "box", "params": {"width": 4, "depth": 0.1, "height": 2.6}},
         "solve": False}]},
        "model_solution": {"nodes": {"a": {"params": {"depth": {"value": 1.0, "sigma": 0.001, "entered": True,
                                                                "entered_sigma": 0.003}}}}}}
    got = entered_values(Project(Path("x.vebuild.json"), data))
    assert {k: (e.sigma, e.why) for k, e in got.items()} == {
        ("a", "height"): (0.0, "hold"), ("a", "width"): (0.002, "hold"), ("a", "depth"): (0.003, "entered"),
        ("w", "width"): (0.0, "not solved"), ("w", "depth"): (0.0, "not solved"),
        ("w", "height"): (0.0, "not solved")}


def test_stale_results_head_the_limitations():
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class Stale:  # what the provenance gives: a message naming the change and the command
        message: str

    data = {"model": {"nodes": []}}
    got = limitations(Project(Path("x.vebuild.json"), data), (), [Stale("textures: the model changed; run "
                                                                        "vebuild texture PROJECT")])
    assert got[0].kind == "stale" and got[0].items == ("textures: the model changed; run vebuild texture PROJECT",)
    assert [lim.kind for lim in limitations(Project(Path("x.vebuild.json"), data))] == []


@SHARES_COURT
def test_limitations_come_from_the_project(court):
    proj, _, page = court
    project = load_project(proj)
    checks = check_distances(project, SolvedModel.from_project(project))
    items = {lim.kind: lim for lim in limitations(project, checks)}
    faces = project.data["textures"]["faces"]
    unseen = [f for f in faces if f["seen_fraction"] == 0]
    assert unseen, "the example has faces no photo saw"
    lim = items["unseen"]
    assert lim.text.startswith(f"{len(unseen)} of the model's {len(faces)} faces were seen by no photo")
    assert "push-pull" in lim.text
    listed = {line.split(":")[0]: line for line in lim.items}
    for f in unseen:
        assert f" {f['face']} (" in " " + listed[f["node"]].split(": ", 1)[1]
    assert any(line.startswith("wall_west") for line in items["not-photographed"].items)
    assert any(line.startswith("table.leg1: height") for line in items["entered"].items)
    failed = [line.split(": ")[0] for line in items["failed-checks"].items]
    assert "T2 – C1" in failed and failed == [f"{c.a} – {c.b}" for c in checks if not c.within_ci95]
    modes = {line.split(":")[0] for line in items["calibration-modes"].items}
    assert modes == set(project.data["calibration"]["cameras"])
    assert "relative-units" not in items and "outliers" not in items  # the example has a scale and no outliers
    for lim in items.values():
        assert f"<h3>{lim.title}</h3>" in page


@SHARES_COURT
def test_title_page_plan_view_and_marked_photos(court):
    proj, out, page = court
    project = load_project(proj)
    title = page[page.index("<div class='findings'>"):page.index(">Evidence views<")]
    title += page[page.index(">Identification<"):page.index(">Photographs<")]
    title += page[page.index(">Declaration<"):page.index("class='annex'")]  # closing the body
    for value in CASE.values():
        assert value in title
    # The state the report was made from, by the digest every output names it by (not the file's own
    # SHA-256, which moves with the audit trail's times).
    assert inputs_sha256(project.data) in title and sha256_file(proj) not in title
    assert "vebuild 0." in title and ">6 (each listed" in title
    # The plan: written deterministically, in the page and in the digest.
    svg = (out / "images" / "plan.svg").read_text()
    assert svg == plan_svg(project, max_height_mm=PLAN_HEIGHT_MM)[0] and svg.startswith("<svg ")
    assert "<img class='plan' src='images/plan.svg'>" in page
    for pid in project.data["calibration"]["cameras"]:
        assert f">{pid}</text>" in svg
    assert "1 : 100 as printed" in svg and "+x</text>" in svg and "origin" in svg
    before = digest(out)
    (out / "images" / "plan.svg").write_text(svg.replace("#2060c0", "#2060c1"))
    assert digest(out) != before
    (out / "images" / "plan.svg").write_text(svg)
    # The photos as marked: each photo at the report's width, its marks drawn, the same bytes each run.
    from PIL import Image

    for i, p in enumerate(project.data["photos"]):
        path = out / "images" / f"marks-{i + 1}.png"
        assert f"src='images/{path.name}'" in page
        img = np.asarray(Image.open(path).convert("RGB"))
        assert img.shape == (720, 960, 3)
        again, counts = marked_photo(project, i, 960)
        assert np.array_equal(again, img)
        assert counts["markers"] == len(p["marker_observations"]) and counts["segments"] > 0
        plain = np.asarray(Image.open(ROOM / p["file"]).convert("RGB").resize((960, 720), Image.Resampling.LANCZOS))
        assert np.mean(np.any(plain != img, axis=2)) > 0.005  # marks were drawn over it


def test_case_command(tmp_path, capsys):
    folder = tmp_path / "room"
    shutil.copytree(ROOM, folder, ignore=shutil.ignore_patterns("textures"))
    proj = folder / "room.vebuild.json"
    assert main(["case", str(proj), "--number", "17/2026", "--examiner", "B"]) == 0
    assert json.loads(proj.read_text())["case"] == {"number": "17/2026", "examiner": "B"}
    assert main(["case", str(proj), "--number", ""]) == 0  # an empty text removes the field
    assert json.loads(proj.read_text())["case"] == {"examiner": "B"}
    capsys.readouterr()
    assert main(["case", str(proj)]) == 0
    assert "examiner:" in capsys.readouterr().out
